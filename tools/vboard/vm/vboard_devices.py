# Wiring of the virtual board: which simulated device sits on which bus/pin,
# and the temperature the board goes through.  The host copies this file into
# the VM at every boot (replace it with --devices FILE / VBOARD_DEVICES).
#
# Pin and bus numbers must match boards/virtual.py, which is the user-side
# view of the same PCB.
#
# Device models are MicroPython modules found in tools/vboard/vm/ or in the
# directories given with --models DIR / VBOARD_MODELS; the interfaces they
# implement are described at the top of vboard.py.  Each model below is
# optional so that the board still boots while one is being written.

I2C_BUS = 0
MPU6500_ADDR = 0x68
SPI_BUS = 0
MLX90609_CS = 17
ADC_RATE = 26  # analog gyro rate output
ADC_TEMP = 27  # analog gyro temperature output

# The room the board sits in, chosen with --scenario (VBOARD_SCENARIO): [(s, degC), ...] over
# board time (vboard.py, "Time"), held after the last point.  The default holds a steady
# room temperature, so a calibration stays inside its span; the others warm or cool the
# board over minutes (stretch them with VBOARD_TIME_SCALE < 1).
SCENARIOS = {
    "steady": [(0, 25.0)],
    "heating": [(0, 25.0), (20, 25.0), (60, 45.0)],
    "cooling": [(0, 45.0), (20, 45.0), (60, 25.0)],
    "cycle": [(0, 25.0), (20, 25.0), (60, 45.0), (80, 45.0), (120, 25.0)],
}


def profile():
    """The temperature profile: VBOARD_PROFILE ("s:degC,...") when the host set one, else the scenario's."""
    import vboard_config

    text = getattr(vboard_config, "PROFILE", "")
    if not text:
        return SCENARIOS[getattr(vboard_config, "SCENARIO", "steady")]
    pts = []
    for item in text.split(","):
        s, c = item.split(":")
        pts.append((float(s), float(c)))
    return pts


def setup(board):
    board.set_profile(profile())
    # The simulated MPU-6500, MLX90609 and analog gyro (tools/sim), moved by
    # vboard_sensors.world: see that module for the parts' true properties.
    import vboard_sensors

    vboard_sensors.wire(board, I2C_BUS, MPU6500_ADDR, SPI_BUS, MLX90609_CS, ADC_RATE, ADC_TEMP)
