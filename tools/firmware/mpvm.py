"""Run code in the real MicroPython WebAssembly VM from the host (see tools/firmware/mpvm.mjs).

host_tests/device/ (scripts that run inside an interpreter, shared by tests and benchmarks) is
mounted at /vmtest and importable."""
import os
import subprocess

from tools import REPO

RUNNER = os.path.join(REPO, "tools", "firmware", "mpvm.mjs")
VM_TEST_DIR = os.path.join(REPO, "host_tests", "device")


class VMError(AssertionError):
    pass


def run(code, mounts=(), paths=(), heap="1m", timeout=120, symlinks=()):
    """Run code in a fresh VM with lib/ at /lib and host_tests/device/ importable; return stdout.

    symlinks: (link, target) pairs made in the VM's filesystem before the code runs."""
    cmd = ["node", RUNNER, "--heap", heap, "--mount", VM_TEST_DIR + ":/vmtest", "--path", "/vmtest"]
    for m in mounts:
        cmd += ["--mount", m]
    for link, target in symlinks:
        cmd += ["--symlink", "%s=%s" % (link, target)]
    for p in paths:
        cmd += ["--path", p]
    cmd += ["-c", code]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:
        raise VMError("MicroPython VM timed out after %ss; output so far:\n%s" % (timeout, e.stdout)) from None
    if proc.returncode != 0:
        raise VMError("MicroPython VM failed (exit %d):\n%s\n%s" % (proc.returncode, proc.stdout, proc.stderr))
    return proc.stdout


def alloc_lines(out):
    """Parse allocprobe.report lines: {name: (bytes_per_call, locked_ok)}."""
    res = {}
    for line in out.splitlines():
        if line.startswith("ALLOC "):
            _, name, b, ok = line.split()
            res[name] = (float(b), ok == "ok")
    return res
