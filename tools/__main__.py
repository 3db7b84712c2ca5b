"""One front door for the host commands: ``python -m tools <command> [args]``.

``python -m tools --help`` lists the commands; ``python -m tools <command> --help`` shows each
one's options and an example. The long spellings (``python -m tools.fit``, ``python -m tools.simgap``,
``python -m tools.board.storetool``...) keep working: this only dispatches to them.
"""
import importlib
import os
import sys

from tools import REPO

# name: (module whose main(argv) runs it, one line, an example)
COMMANDS = {
    "fit": ("tools.fit.__main__", "fit coefficients from a chamber CSV, or a fleet of units (an12760, adxrs, sixpos)",
            "python -m tools fit an12760 cal/accel_x.csv --json cal/accel_x.json"),
    "gap": ("tools.simgap.__main__", "sim-to-real gap diagnosis of a temperature log",
            "python -m tools gap train.csv --withheld held.csv --json out/gap.json --plot out/gap.png"),
    "replay": ("tools.simgap.replay", "run the on-device compensation over a log in the real VM",
               "python -m tools replay model.json held.csv --json out/replay.json"),
    "convert": ("tools.simgap.convert", "convert the real logs in ../shared/data to the log schema",
                "python -m tools convert --out out/real"),
    "gap-check": ("tools.gapbench.check", "the gap diagnosis' blind benchmark",
                  "python -m tools gap-check --small"),
    "board": (None, "the virtual board: MicroPython VM serving a board's REPL",
              "python -m tools board --port 2323"),
    "deploy": ("tools.board.deploy", "install tempcomp and a board module on a board with mpremote",
               "python -m tools deploy --port /dev/ttyACM0 --board pico"),
    "mpy": ("tools.board.build_mpy", "compile lib/ to .mpy with mpy-cross",
            "python -m tools mpy build/mpy"),
    "dist": ("tools.board.dist", "mip-installable .mpy package per .mpy version (make dist)",
             "python -m tools dist dist"),
    "freeze": ("tools.board.freeze", "build AN385 firmware with tempcomp frozen in (proves manifest.py)",
               "python -m tools freeze build/fw-frozen"),
    "store": ("tools.board.storetool", "read, write and export coefficient-store files",
              "python -m tools store dump tempcomp.cal"),
    "bench": ("tools.bench.__main__", "speed, memory and precision figures (make bench)",
              "python -m tools bench core"),
    "demo": ("tools.demo.__main__", "the virtual board end to end (make demo)",
             "python -m tools demo"),
}


def usage(out):
    out.write("usage: python -m tools <command> [args]   (python -m tools <command> --help)\n\n"
              "commands:\n")
    for name, (_, line, example) in COMMANDS.items():
        out.write("  %-10s %s\n  %-10s   e.g. %s\n" % (name, line, "", example))


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        usage(sys.stdout)
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        sys.stderr.write("error: unknown command %r\n" % name)
        usage(sys.stderr)
        return 2
    module, _, example = COMMANDS[name]
    if module is None:  # the virtual board is a node program
        server = os.path.join(REPO, "tools", "vboard", "server.mjs")
        # no code from strings in any thread: a second wall behind the VM's sealed js bridge
        # (tools/vboard/vm_worker.mjs), which holds without it (host_tests/board/test_vboard_security.py);
        # the server thread's heap bounded (the VM's thread and memory are bounded by the server)
        os.execvp("node", ["node", "--disallow-code-generation-from-strings", "--max-old-space-size=256",
                           server] + rest)
    if rest[:1] in (["-h"], ["--help"]):
        print("example: %s\n" % example)
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name != module:
            raise
        sys.stderr.write("error: %s is not available in this checkout\n" % name)
        return 2
    try:
        return mod.main(rest)
    except SystemExit as e:  # argparse's --help and usage errors (int), a command's own message (str)
        if e.code is None or isinstance(e.code, int):
            return e.code or 0
        # as the interpreter does with SystemExit("why"): the message on stderr, exit status 1
        sys.stderr.write("%s\n" % (e.code,))
        return 1
    except OSError as e:
        # a file or directory the command could not read or write (an output under a plain
        # file, a full disk, no permission): one line naming it, like every other bad input
        if e.filename is None:
            raise
        from tools import hostio

        return hostio.fail("%s: %s" % (e.filename, e.strerror or e))


if __name__ == "__main__":
    sys.exit(main())
