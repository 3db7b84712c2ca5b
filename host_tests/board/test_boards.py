"""Board modules: each defines the common names, and the host one builds real Blinka buses."""

import ast
import os

from tools.board import build_mpy

BOARDS = os.path.join(build_mpy.REPO, "boards")
COMMON = {"NAME", "ADC_VREF_MV", "i2c", "spi", "mlx_cs", "adc"}


def _names(path):
    tree = ast.parse(open(path).read())
    out = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out.add(node.name)
        elif isinstance(node, ast.Assign):
            out.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return out


def test_every_hardware_board_module_defines_the_common_names():
    for board in ("pico", "esp32_devkit", "feather_rp2040", "host"):
        missing = COMMON - _names(os.path.join(BOARDS, board + ".py"))
        assert not missing, "boards/%s.py lacks %s" % (board, sorted(missing))


def test_host_board_builds_real_blinka_buses():
    import busio

    from boards import host

    i2c = host.i2c()
    spi = host.spi()
    assert isinstance(i2c, busio.I2C) and isinstance(spi, busio.SPI)
    assert i2c.try_lock()
    i2c.unlock()
