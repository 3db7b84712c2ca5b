"""The REPL read-outs of ``tempcomp.sensors.Sensors``: ``temp_c()``, ``read(n)`` and ``show(n)``.

Floats and formatting, for a person at the REPL; ``Sensors`` loads this module on the first
call, so a board that only reads compensated samples never holds it (docs/ram.md).
"""

ADXRS_NULL_MV = 2500.0  # datasheet null of an ADXRS6xx at 5 V: what an uncalibrated reading assumes
_GYRO_REG_OUT = 4  # one gyro offset register LSB moves the +-250 dps output by 4 LSB
_GYRO_LSB_DPS = 131.0
_CHECK_MS = 1000  # read() re-checks the MPU's offset registers at most this often
_BUF = [0] * 7  # read()'s MPU sample (one REPL read-out at a time)


def temp_c(s):
    """Board temperature, degC (float): the MPU's sensor, else the MLX90609's TEMPOUT."""
    if s.mpu is not None:
        return s.mpu.temp_c100() / 100.0
    mlx = s.mlx
    if mlx is not None and mlx.table is not None:
        return mlx_degc(mlx.table.tc, mlx.tempout_mv())
    return None

def read(s, n=16):
    """Mean of n samples: dict of (compensated, uncompensated) deg/s per axis, and degC.

    Uncompensated is what the part gives with no calibration at all: the MPU's output
    with its offset registers at zero, the MLX90609's code against its nominal 2.5 V
    zero and scale, the analog gyro's voltage against the datasheet null and scale.
    """
    out = {"temp_c": temp_c(s)}  # type: dict
    mpu = s.mpu
    if mpu is not None:
        # compensated: offset(T) in software when a BiasModel is in use, else the output
        # with the calibrated offset registers (room-temperature calibration only)
        b = _BUF
        comp = [0.0, 0.0, 0.0]
        raw = [0, 0, 0]
        if mpu.written is not None:  # offsets written here: keep them (ICM-20602 trim)
            mpu.check(every_ms=_CHECK_MS)
        regs = mpu.offsets()[0]
        tc = mpu.compensating()  # software offset(T): a BiasModel, or its mpu_tcc record
        for _ in range(n):
            if tc:
                mpu.read_compensated(b)
                for k in range(3):
                    comp[k] += b[3 + k]
            mpu.read_raw(b)
            for k in range(3):
                if not tc:
                    comp[k] += b[4 + k] * 1000 / _GYRO_LSB_DPS
                raw[k] += b[4 + k] - _GYRO_REG_OUT * regs[k]
        for k in range(3):
            out["mpu_g" + "xyz"[k]] = (comp[k] / (1000.0 * n), raw[k] / (_GYRO_LSB_DPS * n))
    mlx = s.mlx
    if mlx is not None and mlx.table is not None:
        s0 = mlx.table.s0("digital")
        zero = (2500 - 400) * 12 / 25.0  # the code of a 2.5 V output
        sc = sr = 0
        for _ in range(n):
            sc += mlx.rate()
            sr += mlx.rate_code()
        out["mlx"] = (sc / (float(mlx.out_scale) * n), (sr / n - zero) / s0)
    if s.adxrs is not None:
        a = s.adxrs
        sc = sr = 0
        for _ in range(n):
            if a.comp is not None:
                sc += a.rate()
            sr += a.read_codes()[1]
        mv = sr * a.mv_per_code / n
        c = sc / (float(a.out_per_dps) * n) if a.comp is not None else None
        out["adxrs"] = (c, (mv - ADXRS_NULL_MV) / s.adxrs_mv_per_dps)
    return out

def show(s, n=16):
    """Print temperature and compensated (uncompensated) rates, deg/s; returns None (the REPL
    would echo a returned dict after the line; ``read(n)`` gives the values)."""
    r = read(s, n)
    parts = []
    t = r.get("temp_c")
    if t is not None:
        parts.append("%.2f degC" % t)
    for key in ("mpu_gx", "mpu_gy", "mpu_gz", "mlx", "adxrs"):
        if key in r:
            c, u = r[key]
            parts.append("%s %s (raw %+.3f)" % (key, "--" if c is None else "%+.3f" % c, u))
    print("  ".join(parts))


def mlx_degc(tc, tempout_mv):
    """degC from TEMPOUT (mV) through the table's TC at -40/25/85 degC, piecewise linear."""
    if tempout_mv <= tc[1]:
        return 25.0 + 65.0 * (tempout_mv - tc[1]) / (tc[1] - tc[0])
    return 25.0 + 60.0 * (tempout_mv - tc[1]) / (tc[2] - tc[1])
