"""Board modules: pins and bus set-up for each supported board (one module per board).

Each module defines the same names: ``i2c()``, ``spi()``, ``mlx_cs()``, ``adc(name)``
(``"rate"`` or ``"temp"``), ``ADC_VREF_MV`` and ``NAME``. Copy the one for your board to the
board's /lib as ``tempcomp_board.py`` (``make deploy`` does) and import it from there.
"""
