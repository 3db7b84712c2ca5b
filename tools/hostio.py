"""Files of the host commands: one-line errors naming the file and line, strict JSON, all-or-nothing outputs.

Every ``python -m tools <command>`` reads its inputs and writes its outputs through these helpers,
so that bad input ends in one line ``error: FILE line N: what is wrong`` on stderr with exit
status 2 (never a traceback), and a run that fails part-way leaves no output behind as if it had
succeeded: outputs are checked to be writable before the work starts and are written to a
temporary name beside the target, renamed into place only when every one of them is complete.
"""

import argparse
import json
import math
import os
import sys
import tempfile

EXIT_BAD_INPUT = 2


class HostError(ValueError):
    """A problem with a file the user named; str() is the one line to print."""


def one_line(msg):
    """msg on one line: newlines and runs of blanks become one space, invisible characters escaped."""
    s = " ".join(str(msg).split())
    return "".join(c if c.isprintable() else "\\x%02x" % ord(c) if ord(c) < 256 else "\\u%04x" % ord(c)
                   for c in s)


def fail(msg, out=None):
    """Print ``error: msg`` on one line to stderr; returns the exit status (2)."""
    (out or sys.stderr).write("error: %s\n" % one_line(msg))
    return EXIT_BAD_INPUT


def _os_reason(e):
    if isinstance(e, FileNotFoundError):
        return "no such file or directory"
    if isinstance(e, IsADirectoryError):
        return "is a directory, not a file"
    if isinstance(e, NotADirectoryError):
        return "a part of the path is not a directory"
    if isinstance(e, PermissionError):
        return "permission denied"
    return e.strerror or e.__class__.__name__


def read_bytes(path):
    """The bytes of an input file; HostError naming it when it cannot be read."""
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as e:
        raise HostError("%s: cannot read: %s" % (path, _os_reason(e))) from None


def decode_text(data, path):
    """UTF-8 text of data (a leading BOM dropped); HostError naming the line of a bad byte or a NUL."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        col = e.start - (data.rfind(b"\n", 0, e.start) + 1) + 1
        raise HostError("%s line %d: byte 0x%02x at column %d is not UTF-8 text (binary data or another "
                        "encoding: save the file as UTF-8)" % (path, line, data[e.start], col)) from None
    nul = text.find("\0")
    if nul >= 0:
        raise HostError("%s line %d: a NUL byte: binary data, not a text file"
                        % (path, text.count("\n", 0, nul) + 1))
    return text


def read_text(path):
    """An input text file as str (UTF-8, BOM dropped); HostError naming the file (and line)."""
    return decode_text(read_bytes(path), path)


def number(cell):
    """float(cell) for a cell of an input table, but not Python's digit-grouping underscores:
    '124_956178' is a damaged '124.956178' (a flipped byte; test_bad_input at TEMPCOMP_SEED=51),
    not 124956178. ValueError as float() gives."""
    if "_" in cell:
        raise ValueError(cell)
    return float(cell)


def _reject_constant(name):
    raise ValueError(name)


def load_json(path):
    """Strict JSON from a file (no NaN/Infinity); HostError naming the file, line and column."""
    text = read_text(path)
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise HostError("%s line %d column %d: not valid JSON: %s" % (path, e.lineno, e.colno, e.msg)) from None
    except ValueError as e:
        raise HostError("%s: %s is not a JSON number (strict JSON has no NaN or Infinity)" % (path, e)) from None
    except RecursionError:
        raise HostError("%s: JSON nested too deeply" % path) from None


def nonfinite(obj, where="result"):
    """The key path of the first NaN or infinite float in obj (dicts, lists), or None."""
    if isinstance(obj, float):
        return None if math.isfinite(obj) else where
    if isinstance(obj, dict):
        for k, v in obj.items():
            bad = nonfinite(v, "%s.%s" % (where, k))
            if bad:
                return bad
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            bad = nonfinite(v, "%s[%d]" % (where, i))
            if bad:
                return bad
    return None


def dumps(obj, indent=None):
    """Strict JSON text (a trailing newline); HostError naming a NaN/inf field instead of writing it."""
    bad = nonfinite(obj)
    if bad:
        raise HostError("%s is not a finite number: the data cannot support this fit (an extreme or "
                        "overflowing value?); nothing written" % bad)
    return json.dumps(obj, indent=indent, allow_nan=False) + "\n"


def check_output(path, what="output"):
    """HostError now, before any work, if path cannot be written as a file."""
    if path in (None, "-"):
        return
    if os.path.isdir(path):
        raise HostError("%s: cannot write the %s: it is a directory" % (path, what))
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise HostError("%s: cannot write the %s: directory %s does not exist" % (path, what, d))
    if not os.access(d, os.W_OK | os.X_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        raise HostError("%s: cannot write the %s: permission denied" % (path, what))


def write_all(items):
    """Write every (path, str or bytes) or none: temporary files beside each target, renamed at the end.

    path "-" is standard output (written last). HostError naming the path on any failure; the
    renames come only after every file is complete, so a failure while writing changes no target.
    """
    temps = []
    stdout = []
    try:
        for path, data in items:
            if path in (None, "-"):
                stdout.append(data)
                continue
            check_output(path)
            d = os.path.dirname(os.path.abspath(path))
            try:
                fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=d)
            except OSError as e:
                raise HostError("%s: cannot write: %s" % (path, _os_reason(e))) from None
            temps.append((tmp, path))
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(data.encode("utf-8") if isinstance(data, str) else data)
                umask = os.umask(0)
                os.umask(umask)
                os.chmod(tmp, 0o666 & ~umask)
            except OSError as e:
                raise HostError("%s: cannot write: %s" % (path, _os_reason(e))) from None
        for tmp, path in temps:
            try:
                os.replace(tmp, path)
            except OSError as e:
                raise HostError("%s: cannot write: %s" % (path, _os_reason(e))) from None
        temps = []
    finally:
        for tmp, _ in temps:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    for data in stdout:
        if isinstance(data, bytes):
            sys.stdout.buffer.write(data)
        else:
            sys.stdout.write(data)
        sys.stdout.flush()


class Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line (``error: ...``, exit status 2) like every other error."""

    def error(self, message):
        fail("%s: %s (see %s --help)" % (self.prog, message, self.prog))
        sys.exit(EXIT_BAD_INPUT)
