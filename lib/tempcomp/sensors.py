"""The calibrated sensors of a board, opened from its board module and re-applied from flash.

``tempcomp.session`` calibrates and saves; after any reset one call brings it all back::

    import tempcomp_board
    from tempcomp.sensors import restore
    s = restore(tempcomp_board)      # finds the parts, re-applies what the session saved
    s.show()                         # one line: temperature and compensated rates
    s.mpu.read_compensated(buf)      # per sample (mg, mdps): zero allocation
    s.mpu.check(every_ms=1000)       # in your loop: re-writes a trim the part changed (ICM-20602)
    s.mlx.rate()                     # milli-deg/s, zero allocation
    s.adxrs.rate()                   # milli-deg/s, zero allocation

A board module (``boards/*.py``, copied as ``tempcomp_board``) provides ``i2c()``, ``spi()``,
``mlx_cs()``, ``adc(name)`` and ``ADC_VREF_MV``; optionally ``MPU6500_ADDR`` (0x68),
``ADC_DIVIDER`` (sensor volts per ADC-pin volt, 1.0) and ``ADXRS_MV_PER_DPS`` (6.0). A part
that does not answer is reported and left out (``Sensors.missing`` says why).

Store names (``tempcomp.store.Store``, default ``/tempcomp.cal``): ``mlx90609`` (table and
re-zero, ``MLX90609.save``), ``mpu6xxx`` (offset registers, ``MPU6xxx.save``), ``mpu_tc``
(``BiasModel.to_ints``), ``adxrs`` (``AnalogGyro.to_record``).
"""

# Each driver is imported when its part is looked for, so a board with one MPU never loads
# the MLX90609 or analog gyro code (docs/ram.md). The names below are for the type checker.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from tempcomp.adxrs import AnalogGyro  # noqa: F401  (type comments)
    from tempcomp.mlx90609 import MLX90609  # noqa: F401
    from tempcomp.mpu6xxx import MPU6xxx  # noqa: F401
    from tempcomp.mpu6xxx_tc import BiasModel  # noqa: F401

STORE_PATH = "/tempcomp.cal"
MLX = "mlx90609"
MPU = "mpu6xxx"
MPU_TC = "mpu_tc"
MPU_TCC = "mpu_tcc"  # mpu_tc's set-up for the saved ranges and offsets (tempcomp.mpu6xxx_tc.compiled)
ADXRS = "adxrs"
ALL = (MLX, MPU, ADXRS)

_VT_MIN_MV = 1000  # a temperature output outside this window means no analog gyro is wired
_VT_MAX_MV = 4000


class Sensors:
    """The parts found on a board: ``mlx``, ``mpu``, ``adxrs`` (None when absent)."""

    def __init__(self, board):
        self.board = board
        self.mlx = None  # type: MLX90609 | None
        self.mpu = None  # type: MPU6xxx | None
        self.adxrs = None  # type: AnalogGyro | None
        self.model = None  # type: BiasModel | None  # the MPU's offset(T) model (None when resumed from mpu_tcc)
        self.missing = {}  # type: dict
        self.restored = []  # type: list
        self.adxrs_mv_per_dps = float(getattr(board, "ADXRS_MV_PER_DPS", 6.0))

    def found(self):
        """Names of the parts that answered."""
        return [n for n, p in ((MLX, self.mlx), (MPU, self.mpu), (ADXRS, self.adxrs)) if p is not None]

    # the REPL read-outs (floats, formatting) live in tempcomp.sensors_show, loaded on first use:
    # a board that only reads compensated samples never holds them (docs/ram.md)
    def temp_c(self):
        """Board temperature, degC (float): the MPU's sensor, else the MLX90609's TEMPOUT."""
        from tempcomp.sensors_show import temp_c

        return temp_c(self)

    def read(self, n=16):
        """Mean of n samples: dict of (compensated, uncompensated) deg/s per axis, and degC.

        Uncompensated is what the part gives with no calibration at all: the MPU's output
        with its offset registers at zero, the MLX90609's code against its nominal 2.5 V
        zero and scale, the analog gyro's voltage against the datasheet null and scale.
        """
        from tempcomp.sensors_show import read

        return read(self, n)

    def show(self, n=16):
        """Print temperature and compensated (uncompensated) rates, deg/s; returns None (the REPL
        would echo a returned dict after the line; ``read(n)`` gives the values)."""
        from tempcomp.sensors_show import show

        show(self, n)


def open_sensors(board, which=ALL):
    """Sensors with every part of ``which`` that answers on the board's buses (uncalibrated)."""
    s = Sensors(board)
    for name in which:
        if name not in ALL:
            raise ValueError("unknown sensor %r; choose from %s" % (name, ", ".join(ALL)))
    if MPU in which:
        try:
            i2c = board.i2c()
            from tempcomp.mpu6xxx import MPU6xxx

            s.mpu = MPU6xxx(i2c, getattr(board, "MPU6500_ADDR", 0x68))
        except (OSError, AttributeError) as e:
            s.missing[MPU] = "no MPU-6xxx on I2C: %s" % (e,)
    if MLX in which:
        try:
            spi = board.spi()
            cs = board.mlx_cs()
            from tempcomp.mlx90609 import MLX90609

            s.mlx = MLX90609(spi, cs)
        except (OSError, AttributeError) as e:
            s.missing[MLX] = "no MLX90609 on SPI: %s" % (e,)
    if ADXRS in which:
        try:
            rate = board.adc("rate")
            temp = board.adc("temp")
            from tempcomp.adxrs import AnalogGyro

            g = AnalogGyro(rate, temp, board.ADC_VREF_MV, getattr(board, "ADC_DIVIDER", 1.0))
            vt = g.measure(8)[0]
        except (OSError, AttributeError, KeyError) as e:
            s.missing[ADXRS] = "no analog gyro inputs on this board: %s" % (e,)
        else:
            if _VT_MIN_MV < vt < _VT_MAX_MV:
                s.adxrs = g
            else:
                s.missing[ADXRS] = "no analog gyro: its temperature output reads %d mV" % vt
    return s


def restore(board, path=STORE_PATH, which=ALL, verbose=True):
    """Open the board's parts and re-apply everything saved in the store at path.

    Returns the Sensors, ready for compensated reads. A part with nothing saved is left
    uncalibrated and named in the report; a record that does not fit the part raises
    ValueError (the part keeps its present state).
    """
    from tempcomp.store import Store

    s = open_sensors(board, which)
    st = Store(path)
    try:
        names = st.names()
    except (OSError, ValueError) as e:
        raise OSError("no calibration in %s (%s): run the session first" % (path, e))
    if s.mlx is not None and MLX in names:
        s.mlx.load(st, MLX)
        s.restored.append(MLX)
    mpu = s.mpu
    if mpu is not None:
        if MPU in names:
            mpu.restore(st, MPU)
            s.restored.append(MPU)
        if MPU_TC in names:
            mi = st.load(MPU_TC)
            done = False
            if MPU_TCC in names:
                # the set-up computed at calibration (tempcomp.mpu6xxx_rt): no fixed-point set-up
                # at boot; refused (ValueError) when the part holds other ranges or offsets
                try:
                    mpu.compensate(st.load(MPU_TCC), mi)
                    done = True
                except ValueError:
                    pass
            if not done:
                from tempcomp.mpu6xxx_tc import BiasModel

                model = BiasModel.from_ints(mi)
                mpu.compensate(model)
                s.model = model
            s.restored.append(MPU_TC)
    if s.adxrs is not None and ADXRS in names:
        s.adxrs.load_record(st.load(ADXRS))
        s.restored.append(ADXRS)
    if verbose:
        print("restored from %s: %s" % (path, ", ".join(s.restored) or "nothing"))
        for name in s.found():
            if name not in s.restored:
                print("  %s: nothing saved, uncalibrated" % name)
        for name in s.missing:
            print("  %s" % s.missing[name])
        if mpu is not None and MPU in s.restored and mpu.part == "ICM-20602":
            print("  ICM-20602: it can rewrite its accel trim by itself; call s.mpu.check(every_ms=1000) "
                  "from your loop to keep the offsets (read() and show() do)")
    return s
