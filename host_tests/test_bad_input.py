"""Bad input everywhere gets one clear line: a fuzz over every host command that reads a file.

Each command's valid input is damaged the ways files really get damaged (a truncated line, flipped
bytes, a deleted cell, another encoding, a BOM, CRLF, NUL bytes, binary garbage, 1e308 and NaN
cells, an empty file). Every run either succeeds with strict-JSON output, or exits with status 2
and exactly one stderr line ``error: ...`` naming the damaged file (and the line, for damage a
line can show), leaves no output behind, and never raises. The commands run in-process through
the front door (``tools.__main__.main``, as ``python -m tools`` does); a few run as real
subprocesses. Unwritable outputs, bad option values and wrong-kind files are covered too.
"""

import json
import os
import pathlib
import random
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import seeds
import simgap_synth
from paths import REPO

from tools.__main__ import main as front_door
from tools.board import storetool
from tools.fit import simulate as S
from tools.sim.analog_gyro_sim import AnalogGyroSim
from tools.simgap.convert import PAN_REL, TOFU_REL
from tools.simgap.logio import write_log

SEEDS = tuple(seeds.seeds("bad_input", 3))  # drawn per run: TEMPCOMP_SEED repeats them


def _strict(text):
    def bad(c):
        raise AssertionError("non-strict JSON constant %s" % c)

    return json.loads(text, parse_constant=bad)


# -- valid inputs ------------------------------------------------------------------------------

def _an12760_csv(unit=None):
    rng = np.random.default_rng(seeds.seed("bad_input/an12760"))
    head = "temp_c,ref_g,out_mg"
    rows = []
    for t in (-40.0, 25.0, 85.0):
        for g in (-1.0, 1.0):
            for _ in range(3):
                y = 12.0 + 0.3 * (t - 25) + g * 1000 * 1.01 * (1 + 2e-4 * (t - 25)) + rng.normal(0, 0.5)
                rows.append("%g,%g,%.3f" % (t, g, y))
    if unit is None:
        return head + "\n" + "\n".join(rows) + "\n"
    return "unit," + head + "\n" + "\n".join("%s,%s" % (u, r) for u in unit for r in rows) + "\n"


def _adxrs_csv():
    sim = AnalogGyroSim(vref_mv=3300, divider=2.0, noise_mv=0.5, t_noise_mv=0.3, seed=seeds.seed("bad_input/adxrs"))
    q = 3300.0 * 2.0 / 65535
    rows = ["temp_c,vt_mv,rate_dps,out_mv"]
    for t in (-40.0, 25.0, 85.0):
        sim.temp_c = t
        for r in (0.0, 200.0, -200.0):
            sim.rate_dps = r
            for _ in range(3):
                rows.append("%g,%.2f,%g,%.2f" % (t, sim.temp.read_u16() * q, r, sim.rate.read_u16() * q))
    return "\n".join(rows) + "\n"


def _sixpos_csv():
    rng = np.random.default_rng(seeds.seed("bad_input/sixpos"))
    raw = S.chamber(S.truth(1, rng), [-40.0, 25.0, 85.0], S.SIX, 2, 16384.0, rng)
    labels = ["+x", "-x", "+y", "-y", "+z", "-z"]
    rows = ["temp_c,orient,ax,ay,az"]
    for k, t in enumerate((-40.0, 25.0, 85.0)):
        for o in range(6):
            for s in raw[0, k, o]:
                rows.append("%g,%s,%d,%d,%d" % ((t, labels[o]) + tuple(int(v) for v in s)))
    return "\n".join(rows) + "\n"


def _gap_log(path, k=0):
    log = simgap_synth.make(n=300, seed=seeds.seed("bad_input/gap_log", k))
    cols = {"time_s": log.t, "temp_c": log.temp}
    for a, ax in enumerate("xyz"):
        cols["out_" + ax] = log.out[:, a]
    for a, ax in enumerate("xyz"):
        cols["ref_" + ax] = log.ref[:, a]
    write_log(str(path), cols, {"sensor": "gyro"})


MODEL = {"t0_c": 25.0, "axes": {a: {"offset": [50.0, 4.0, -0.02], "sensitivity": [16.0, 0.0016]} for a in "xyz"}}


def _tofu_text():
    cols = ["imu.gyro.x", "imu.gyro.y", "imu.gyro.z", "imu.acc.x", "imu.acc.y", "imu.acc.z", "imu.temperature"]
    rows = ["\t".join(["timestamp"] + cols)]
    for i in range(40):
        rows.append("\t".join(["%d" % i, "0.001", "-0.002", "0.0005", "0.1", "0.05", "-9.8", "%.2f" % (20 + i * 0.5)]))
    return "\n".join(rows) + "\n"


def _pan_text():
    rows = ["time (ms),gyrox rad/s,gyroy rad/s,gyroz rad/s,temp"]
    for i in range(40):
        rows.append("%d,0.001,-0.002,0.0005,%d" % (i * 10, (i * 37) % 65536))
    return "\n".join(rows) + "\n"


def _store_doc():
    return {"format": 1, "generation": 3, "records": [
        {"name": "acc", "part": "MPU6050", "serial": "A1", "kind": "an12760_axis", "t_unit": "centi_degC",
         "t_span": [-4000, 8500], "counter": 3, "time": 0, "values": [12, -340, 7], "frac": [0, 4, 8]},
        {"name": "gyro", "values": [1, 2], "frac": [0, 0]}]}


# -- the commands: (name, is_text, build(dir) -> (fuzzed file, argv, outputs)) -------------------

def _t_fit(cmd, make, extra=()):
    def build(d):
        f = d / ("in.csv")
        f.write_text(make())
        o = d / "out.json"
        return f, ["fit", cmd, str(f), "--json", str(o), "--record", str(d / "rec.json")] + list(extra), [o]
    return build


def _t_fleet_dir(d):
    u = d / "units"
    u.mkdir()
    for k in range(3):
        (u / ("SN%d.csv" % k)).write_text(_sixpos_csv())
    o = d / "out.json"
    return u / "SN1.csv", ["fit", "sixpos", str(u), "--counts-per-g", "16384", "--json", str(o),
                           "--summary", str(d / "s.csv")], [o, d / "s.csv"]


def _t_fleet_col(d):
    f = d / "line.csv"
    f.write_text(_an12760_csv(unit=("A", "B", "C")))
    o = d / "out.json"
    return f, ["fit", "an12760", str(f), "--json", str(o)], [o]


def _t_gap(d):
    f = d / "train.csv"
    _gap_log(f)
    o = d / "gap.json"
    return f, ["gap", str(f), "--json", str(o), "--quiet"], [o]


def _t_gap_withheld(d):
    _gap_log(d / "train.csv")
    f = d / "held.csv"
    _gap_log(f, k=1)
    o = d / "gap.json"
    return f, ["gap", str(d / "train.csv"), "--withheld", str(f), "--json", str(o), "--quiet"], [o]


def _t_gap_model(d):
    _gap_log(d / "train.csv")
    f = d / "model.json"
    f.write_text(json.dumps(MODEL, indent=1))
    o = d / "gap.json"
    return f, ["gap", str(d / "train.csv"), "--model", str(f), "--json", str(o), "--quiet"], [o]


def _t_convert(which):
    def build(d):
        data = d / "data"
        for rel, text in ((TOFU_REL, _tofu_text()), (PAN_REL, _pan_text())):
            (data / rel).parent.mkdir(parents=True, exist_ok=True)
            (data / rel).write_text(text)
        f = data / (TOFU_REL if which == "tofu" else PAN_REL)
        return f, ["convert", "--data", str(data), "--out", str(d / "real")], [d / "real"]
    return build


def _t_json2bin(d):
    f = d / "cal.json"
    f.write_text(storetool.to_json(_store_doc()))
    o = d / "cal.bin"
    return f, ["store", "json2bin", str(f), "-o", str(o)], [o]


def _t_store(cmd):
    def build(d):
        f = d / "cal.bin"
        f.write_bytes(storetool.encode_image(_store_doc()))
        o = d / "out.txt"
        argv = ["store", cmd, str(f)] + ([] if cmd == "dump" else ["-o", str(o)])
        return f, argv, ([] if cmd == "dump" else [o])
    return build


TARGETS = {
    "fit-an12760": (True, _t_fit("an12760", _an12760_csv)),
    "fit-adxrs": (True, _t_fit("adxrs", _adxrs_csv)),
    "fit-sixpos": (True, _t_fit("sixpos", _sixpos_csv, ("--counts-per-g", "16384"))),
    "fit-fleet-dir": (True, _t_fleet_dir),
    "fit-fleet-unit-column": (True, _t_fleet_col),
    "gap-train": (True, _t_gap),
    "gap-withheld": (True, _t_gap_withheld),
    "gap-model": (True, _t_gap_model),
    "convert-tofupilot": (True, _t_convert("tofu")),
    "convert-pan": (True, _t_convert("pan")),
    "store-json2bin": (True, _t_json2bin),
    "store-dump": (False, _t_store("dump")),
    "store-bin2json": (False, _t_store("bin2json")),
    "store-export": (False, _t_store("export")),
}


# -- damage -----------------------------------------------------------------------------------

def _data_lines(b):
    """(indices of the data lines: after the '#' metadata and the header, not blank; lines)."""
    lines = b.split(b"\n")
    head = next(i for i, ln in enumerate(lines) if not ln.startswith(b"#") and ln.strip())
    return [i for i, ln in enumerate(lines) if i > head and ln.strip()], lines


def _sep(line):
    return b"\t" if b"\t" in line else b","


def _cells(line):
    return [m for m in range(len(line)) if line[m:m + 1] in (b",", b"\t")]


def _is_number(cell):
    return _NUMBER.match(cell.strip().decode("ascii", "replace")) is not None


def damage(kind, b, rng):
    """(damaged bytes, True when the damage is on a line a message can name). Every kind changes
    the file: a kind that needs a cell picks a line that has one."""
    if kind == "truncate":
        cut = [i for i in range(1, len(b)) if b[i - 1:i] not in (b"\n",)]
        return b[:rng.choice(cut)], False
    if kind == "cut_cell":  # the file ends inside its last number: 1053.246 -> 1053 (a whole-looking row)
        idx, lines = _data_lines(b)

        def ends(ln):  # cuts after a digit that a digit or a point follows
            return [m for m in range(1, len(ln)) if ln[m - 1:m].isdigit() and ln[m:m + 1] in b"0123456789."]

        i = [i for i in idx if ends(lines[i])][-1]
        return b"\n".join(lines[:i] + [lines[i][:rng.choice(ends(lines[i]))]]), False
    if kind == "flip":
        b = bytearray(b)
        for _ in range(rng.randint(1, 3)):
            b[rng.randrange(len(b))] ^= rng.randint(1, 255)
        return bytes(b), False
    if kind == "delete_cell":
        idx, lines = _data_lines(b)
        i = rng.choice([i for i in idx if _cells(lines[i])])
        seps = _cells(lines[i])
        s = rng.choice(seps)
        nxt = [m for m in seps if m > s]
        lines[i] = lines[i][:s] + (lines[i][nxt[0]:] if nxt else b"")
        return b"\n".join(lines), True
    if kind in ("big", "nan"):
        idx, lines = _data_lines(b)
        i = rng.choice([i for i in idx if any(_is_number(p) for p in lines[i].split(_sep(lines[i])))])
        parts = lines[i].split(_sep(lines[i]))
        nums = [k for k, p in enumerate(parts) if _is_number(p)]
        parts[rng.choice(nums)] = b"1e308" if kind == "big" else b"nan"
        lines[i] = _sep(lines[i]).join(parts)
        return b"\n".join(lines), True
    if kind == "utf16":
        return b.decode("utf-8").encode("utf-16"), True
    if kind == "latin1":
        idx, lines = _data_lines(b)
        i = rng.choice(idx)
        lines[i] = lines[i][:3] + "\u00e9".encode("latin-1") + lines[i][3:]
        return b"\n".join(lines), True
    if kind == "nul":
        idx, lines = _data_lines(b)
        i = rng.choice(idx)
        lines[i] = lines[i][:2] + b"\x00" + lines[i][2:]
        return b"\n".join(lines), True
    if kind == "bom":
        return b"\xef\xbb\xbf" + b, False
    if kind == "crlf":
        return b.replace(b"\n", b"\r\n"), False
    if kind == "garbage":
        return bytes(rng.randrange(256) for _ in range(300)), False
    if kind == "empty":
        return b"", False
    if kind == "header_only":  # the metadata and the header line, no data
        lines = b.split(b"\n")
        head = next(i for i, ln in enumerate(lines) if not ln.startswith(b"#") and ln.strip())
        return b"\n".join(lines[:head + 1]) + b"\n", False
    raise ValueError(kind)


# -- what a successful run on damaged input must show -------------------------------------------

# a decimal number as a person or a logger writes it: what float() takes beyond this ("1_3",
# "infinity", other scripts' digits) is damage, not data
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_INT = re.compile(r"^[+-]?\d+$")
LIMIT = 1e12  # the readers' "beyond any reading" (tools/fit/fastcsv.py, tools/simgap/logio.py)


def _text_columns(good):
    """Columns of the undamaged file that are not numbers (a unit id, an orientation label)."""
    rows = _table(good)
    if rows is None:
        return set()
    head, body = rows[1], rows[2]
    return {j for j in range(len(head)) if any(not _NUMBER.match(r[j]) for r in body if j < len(r))}


def _table(b):
    """(comment lines, header cells, rows of stripped cells) of a delimited text file, split only
    at \\n (or \\r\\n) and at the header's delimiter; None if it is not UTF-8 text."""
    try:
        s = b.decode("utf-8")
    except UnicodeDecodeError:
        return None
    if s.startswith("\ufeff"):
        s = s[1:]
    lines = re.split(r"\r?\n", s)
    if lines and lines[-1] == "":
        lines.pop()
    k = 0
    while k < len(lines) and lines[k].startswith("#"):
        k += 1
    if k == len(lines):
        return None
    sep = "\t" if "\t" in lines[k] else ","
    body = [[c.strip() for c in ln.split(sep)] for ln in lines[k + 1:] if ln.strip()]
    return lines[:k], [c.strip() for c in lines[k].split(sep)], body, sep


def canonical_table(b, text_cols):
    """The damaged file as a strict reader of its format sees it, written plainly (one form per
    number, no BOM, \\n): None when that reader refuses it (a row of another width, a cell that
    is not a finite decimal number below LIMIT, a NUL or control character, not UTF-8)."""
    t = _table(b)
    if t is None:
        return None
    comments, head, body, sep = t
    if not body or any("\x00" in c or not c.isprintable() for c in head):
        return None
    out = list(comments) + [sep.join(head)]
    for r in body:
        if len(r) != len(head):
            return None
        cells = []
        for j, c in enumerate(r):
            if j in text_cols:
                if not c or not c.isprintable():
                    return None
                cells.append(c)
            elif _INT.match(c):
                cells.append(str(int(c)))
            elif _NUMBER.match(c) and abs(float(c)) < LIMIT:
                cells.append(repr(float(c)))
            else:
                return None
        out.append(sep.join(cells))
    return ("\n".join(out) + "\n").encode()


def canonical_json(b):
    def refuse(c):
        raise ValueError(c)

    def pairs(kv):
        if len({k for k, _ in kv}) != len(kv):
            raise ValueError("a key twice")
        return dict(kv)

    try:
        obj = json.loads(b.decode("utf-8"), parse_constant=refuse, object_pairs_hook=pairs)
    except ValueError:  # UnicodeDecodeError and json.JSONDecodeError are ValueErrors
        return None
    return (json.dumps(obj, indent=1) + "\n").encode()


def snapshot(outputs, out, base):
    """What a run produced (output files, stdout), with the test's directory taken out of it."""
    def norm(data):
        return data.replace(str(base).encode(), b"<tmp>")

    got = {"stdout": norm(out.encode())}
    for o in outputs:
        o = pathlib.Path(o)
        files = sorted(p for p in o.rglob("*") if p.is_file()) if o.is_dir() else [o] if o.exists() else []
        for p in files:
            got[str(p.relative_to(base))] = norm(p.read_bytes())
    return got


def clear(outputs):
    for o in outputs:
        if os.path.isdir(o):
            shutil.rmtree(o)
        elif os.path.exists(o):
            os.remove(o)


TEXT_KINDS = [(k, s) for k in ("truncate", "cut_cell", "flip", "delete_cell", "big", "nan", "nul", "latin1") for s in SEEDS]
TEXT_KINDS += [(k, 0) for k in ("utf16", "bom", "crlf", "empty", "header_only")] + [("garbage", SEEDS[0])]
BIN_KINDS = [(k, s) for k in ("truncate", "flip") for s in seeds.seeds("bad_input_binary", 6)]
BIN_KINDS += [("garbage", SEEDS[0]), ("empty", 0)]
CASES = [(t, k, s) for t, (text, _) in TARGETS.items() for k, s in (TEXT_KINDS if text else BIN_KINDS)]


def run_front_door(argv, capsys):
    rc = front_door(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def check_outcome(rc, out, err, named, outputs, need_line=False):
    assert "Traceback" not in err and "Traceback" not in out
    if rc == 0:
        for o in outputs:
            if str(o).endswith(".json"):
                _strict(o.read_text())
        return
    assert rc == 2, (rc, err)
    lines = err.splitlines()
    errors = [ln for ln in lines if not ln.startswith("warning: ")]
    assert len(errors) == 1 and errors[0].startswith("error: "), err
    assert str(named) in errors[0], (named, err)
    if need_line:
        assert " line " in errors[0], err
    for o in outputs:
        assert not os.path.exists(o), "%s left behind after a failed run" % o


_UNDAMAGED = {}  # target -> what the undamaged input gives (snapshot)


def canonical(target, good, bad):
    """The damaged file as written plainly by a strict reader of its format, or None (refused)."""
    if target in ("store-json2bin", "gap-model"):
        return canonical_json(bad)
    if not TARGETS[target][0]:
        return None  # a binary store: no two ways of writing the same calibration
    return canonical_table(bad, _text_columns(good))


@pytest.mark.parametrize("target,kind,seed", CASES)
def test_damaged_input(target, kind, seed, tmp_path, capsys):
    """Damaged input gives the one-line error, or the undamaged input's result, or the result of
    the data the damaged file holds: the same as for those data written plainly (a truncated
    last cell 1053.246 -> 1053 must give the fit of 1053, not of the file before the damage nor
    of a row dropped), and the damage must change the file (a no-op damage tests nothing)."""
    _, build = TARGETS[target]
    f, argv, outputs = build(tmp_path)
    good = f.read_bytes()
    if target not in _UNDAMAGED:  # once per command: the undamaged input works
        rc, out, err = run_front_door(argv, capsys)
        assert rc == 0, (target, "the undamaged input must work", err)
        _UNDAMAGED[target] = snapshot(outputs, out, tmp_path)
        clear(outputs)
    bad, line_damage = damage(kind, good, random.Random(seed * 7919 + len(kind)))
    assert bad != good, "%s damage left %s unchanged: this case tests nothing" % (kind, f.name)
    f.write_bytes(bad)
    rc, out, err = run_front_door(argv, capsys)
    # damage a line can show (a deleted cell, 1e308, NaN, a NUL, a non-UTF-8 byte) is named by line
    need = line_damage and rc == 2 and not target.startswith("store-") and target != "gap-model"
    check_outcome(rc, out, err, f, outputs, need_line=need)
    if kind in ("bom", "crlf") and target not in ("store-json2bin",):
        assert rc == 0, (target, kind, err)
    if rc != 0:
        return
    got = snapshot(outputs, out, tmp_path)
    if got == _UNDAMAGED[target]:
        return
    assert kind not in ("bom", "crlf"), (target, kind, "a BOM or CRLF changed the result")
    plain = canonical(target, good, bad)
    assert plain is not None, (target, kind, "exit 0 with a result of its own on a file a strict reader "
                               "refuses: %r" % _differs(good, bad))
    clear(outputs)
    f.write_bytes(plain)
    rc2, out2, err2 = run_front_door(argv, capsys)
    assert rc2 == 0, (target, kind, "the damaged file's data written plainly are refused", err2)
    assert snapshot(outputs, out2, tmp_path) == got, (target, kind, "the result is not that of the data the "
                                                      "damaged file holds: %r" % _differs(good, bad))


def _differs(good, bad):
    # the first damaged line, for the failure message
    g, b = good.split(b"\n"), bad.split(b"\n")
    for i, (x, y) in enumerate(zip(g, b)):
        if x != y:
            return "line %d: %r -> %r" % (i + 1, x[:80], y[:80])
    return "%d lines -> %d lines" % (len(g), len(b))


def test_the_fuzz_covers_every_file_reading_command():
    from tools.__main__ import COMMANDS

    fuzzed = {argv_cmd for argv_cmd in ("fit", "gap", "convert", "store")}
    # the others read no data file: board (node), deploy and mpy (the library), bench, demo,
    # gap-check (generates its own cases), replay (model + log: the gap's readers)
    assert fuzzed <= set(COMMANDS)
    assert len(CASES) >= 300, len(CASES)


# -- outputs that cannot be written, options that make no sense, files of the wrong kind -------

def _unwritable(tmp_path):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    return {"missing-dir": tmp_path / "nodir" / "o.json", "a-directory": tmp_path / "adir",
            "under-a-file": tmp_path / "afile" / "o.json", "proc": "/proc/tempcomp-test.json"}


@pytest.mark.parametrize("where", ["missing-dir", "a-directory", "under-a-file", "proc"])
@pytest.mark.parametrize("target", ["fit-an12760", "fit-fleet-dir", "gap-train", "store-json2bin",
                                    "store-bin2json", "store-export"])
def test_unwritable_output(target, where, tmp_path, capsys):
    f, argv, outputs = TARGETS[target][1](tmp_path)
    bad = _unwritable(tmp_path)[where]
    flag = "-o" if "-o" in argv else "--json"
    argv = list(argv)
    argv[argv.index(flag) + 1] = str(bad)
    rc, out, err = run_front_door(argv, capsys)
    assert rc == 2 and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith("error: ") and str(bad) in err, err
    for o in outputs:
        assert not os.path.exists(o)


def test_a_failing_plot_leaves_no_json(tmp_path, capsys):
    _gap_log(tmp_path / "train.csv")
    o = tmp_path / "gap.json"
    for plot in ("/proc/tempcomp-test.png", str(tmp_path / "gap.pdf"), str(tmp_path / "nodir" / "g.png")):
        rc, out, err = run_front_door(["gap", str(tmp_path / "train.csv"), "--json", str(o), "--plot", plot], capsys)
        assert rc == 2 and err.count("\n") == 1 and plot in err, err
        assert not o.exists()
    rc, out, err = run_front_door(["gap", str(tmp_path / "train.csv"), "--json", str(o), "--plot",
                                   str(tmp_path / "g.png"), "--quiet"], capsys)
    assert rc == 0 and o.exists() and (tmp_path / "g.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv,says", [
    (["fit", "sixpos", "{six}", "--counts-per-g", "0", "--json", "{o}"], "--counts-per-g"),
    (["fit", "sixpos", "{six}", "--counts-per-g", "nan", "--json", "{o}"], "--counts-per-g"),
    (["fit", "sixpos", "{six}", "--counts-per-g", "-16384", "--json", "{o}"], "--counts-per-g"),
    (["fit", "sixpos", "{six}", "--counts-per-g", "lots", "--json", "{o}"], "--counts-per-g"),
    (["fit", "an12760", "{an}", "--temp-tol", "-1", "--json", "{o}"], "--temp-tol"),
    (["fit", "an12760", "{an}", "--order", "7", "--json", "{o}"], "order"),
    (["fit", "sixpos", "{six}", "--counts-per-g", "16384", "--order", "0", "--json", "{o}"], "order"),
    (["fit", "sixpos", "{six}", "--counts-per-g", "16384", "--raw-min", "5", "--raw-max", "-5", "--json", "{o}"],
     "range"),
    (["fit", "an12760", "{an}", "--store", "{notstore}", "--name", "x", "--json", "{o}"], "not a tempcomp store"),
    (["fit", "an12760", "{an}", "--store", "{tmp}", "--name", "x", "--json", "{o}"], "--store"),
    (["fit", "an12760", "{an}", "--store", "{st}", "--json", "{o}"], "--name"),
    (["fit", "an12760", "{tmp}/none.csv", "--json", "{o}"], "none.csv"),
    (["fit", "an12760", "{six}", "--json", "{o}"], "missing column"),
    (["store", "json2bin", "{an}", "-o", "{tmp}/x.bin"], "not valid JSON"),
    (["store", "json2bin", "{six}", "-o", "{tmp}/x.bin", "--nvm", "3"], "{six}"),
    (["store", "dump", "{notstore}"], "not a tempcomp store"),
    (["store", "dump", "{tmp}"], "{tmp}"),
    (["gap", "{an}", "--json", "{o}"], "header lacks"),
    (["gap", "{tmp}/none.csv", "--json", "{o}"], "none.csv"),
])
def test_bad_options_and_wrong_files(argv, says, tmp_path, capsys):
    (tmp_path / "six.csv").write_text(_sixpos_csv())
    (tmp_path / "an.csv").write_text(_an12760_csv())
    (tmp_path / "notstore").write_text("hello, not a store\n" * 3)
    names = {"six": tmp_path / "six.csv", "an": tmp_path / "an.csv", "o": tmp_path / "o.json",
             "notstore": tmp_path / "notstore", "tmp": tmp_path, "st": tmp_path / "cal.bin"}
    argv = [a.format(**names) for a in argv]
    rc, out, err = run_front_door(argv, capsys)
    assert rc == 2 and "Traceback" not in err, err
    assert err.count("\n") == 1 and err.startswith("error: ") and says.format(**names) in err, err
    assert not (tmp_path / "o.json").exists()
    assert (tmp_path / "notstore").read_text().startswith("hello")  # never overwritten


@pytest.mark.parametrize("doc,says", [
    ({"generation": 1, "records": [{"name": "a", "values": [1], "frac": [99]}]}, "frac[0] = 99"),
    ({"generation": 1, "records": [{"name": "a", "values": [1]}, {"name": "a", "values": [2]}]}, "unique"),
    ({"generation": 1, "records": [{"name": "a", "values": [0] * 4097}]}, "4096"),
    ({"generation": 1, "records": [{"name": "a-b", "values": [1]}, {"name": "a_b", "values": [2]}]}, "identifier"),
    ({"generation": 1, "records": [{"name": "a", "values": [2**31]}]}, "values[0]"),
    ({"generation": 1, "records": [{"name": "a", "values": [1.5]}]}, "not an integer"),
    ({"generation": 1, "records": [{"name": "a", "values": [True]}]}, "not an integer"),
    ({"generation": 1, "records": [{"name": "", "values": [1]}]}, "name"),
    ({"generation": 1, "records": [{"name": "x" * 33, "values": [1]}]}, "name"),
    ({"generation": 1, "records": [{"name": "caf\u00e9", "values": [1]}]}, "printable ASCII"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "kind": "teapot"}]}, "kind"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "kind": 300}]}, "kind"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "t_span": [5, 1]}]}, "t_span"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "counter": 5}]}, "counter"),
    ({"generation": 1, "records": [{"name": "a", "real": [1e300], "frac": [0]}]}, "real[0]"),
    ({"generation": 1, "records": [{"name": "a"}]}, "neither values nor real"),
    ({"generation": 1, "records": ["a"]}, "not an object"),
    ({"generation": 1, "records": {}}, "records must be a list"),
    ({"generation": 0, "records": []}, "generation"),
    ({"generation": "1", "records": []}, "generation"),
    ({"records": []}, "generation"),
    ([], "must be an object"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "part": "x" * 17}]}, "part"),
    ({"generation": 1, "records": [{"name": "a", "values": [1], "frac": [0, 0]}]}, "frac"),
])
def test_storetool_refuses_what_the_device_would(doc, says, tmp_path, capsys):
    j = tmp_path / "cal.json"
    j.write_text(json.dumps(doc))
    rc, out, err = run_front_door(["store", "json2bin", str(j), "-o", str(tmp_path / "cal.bin")], capsys)
    assert rc == 2 and err.count("\n") == 1 and says in err and str(j) in err, err
    assert not (tmp_path / "cal.bin").exists()


def test_export_refuses_names_that_collide_as_identifiers(tmp_path, capsys):
    from tempcomp.store import Store

    p = str(tmp_path / "cal.bin")
    st = Store(p)
    st.save("a-b", (1,))
    st.save("a_b", (2,))
    rc, out, err = run_front_door(["store", "export", p, "-o", str(tmp_path / "c.py")], capsys)
    assert rc == 2 and "A_B" in err and err.count("\n") == 1
    assert not (tmp_path / "c.py").exists()


@pytest.mark.parametrize("argv_tail,says", [
    (["fit", "an12760", "IN", "--json", "OUT"], "line 3"),
    (["gap", "IN", "--json", "OUT"], "line"),
    (["store", "json2bin", "IN", "-o", "OUT"], "UTF-8"),
    (["fit", "sixpos", "IN", "--counts-per-g", "0", "--json", "OUT"], "--counts-per-g"),
])
def test_real_command_lines(argv_tail, says, tmp_path):
    f = tmp_path / "in.csv"
    f.write_bytes(b"temp_c,ref_g,out_mg\n25,1,1000\n2\xff5,-1,-1000\n")
    o = tmp_path / "out.json"
    argv = [str(f) if a == "IN" else str(o) if a == "OUT" else a for a in argv_tail]
    p = subprocess.run([sys.executable, "-m", "tools"] + argv, cwd=REPO, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("error: ") and says in p.stderr, p.stderr
    assert not o.exists()


def test_records_the_device_would_refuse_are_not_written(tmp_path, capsys):
    # an axis wired inverted: sensitivity -1000 mg/g fits (finite) but gives sen_tol -2, which
    # tempcomp.an12760 refuses (sensitivity must stay positive)
    f = tmp_path / "inv.csv"
    f.write_text("temp_c,ref_g,out_mg\n" + "".join("%g,%g,%g\n" % (t, g, -1000 * g + 0.1 * t)
                                                     for t in (-40, 25, 85) for g in (-1, 1)))
    o = tmp_path / "o.json"
    rc, out, err = run_front_door(["fit", "an12760", str(f), "--json", str(o)], capsys)
    assert rc == 2 and "the device would refuse this record" in err and "sen_tol" in err, err
    assert err.count("\n") == 1 and not o.exists()


@pytest.mark.parametrize("out_mv,says", [
    (lambda t, r: 2500.0, "stuck rate output"),                       # the output never moves
    (lambda t, r: 2500.0 + r * (6.0 if t < 50 else -6.0), "changes sign"),
])
def test_adxrs_output_that_does_not_follow_the_rate(out_mv, says, tmp_path, capsys):
    f = tmp_path / "g.csv"
    rows = ["temp_c,vt_mv,rate_dps,out_mv"]
    for t in (-40.0, 25.0, 85.0):
        for r in (0.0, 200.0, -200.0):
            for k in range(3):
                rows.append("%g,%.2f,%g,%.3f" % (t, 2500 + 9 * (t - 25), r, out_mv(t, r) + 0.01 * k))
    f.write_text("\n".join(rows) + "\n")
    o = tmp_path / "o.json"
    rc, out, err = run_front_door(["fit", "adxrs", str(f), "--json", str(o)], capsys)
    assert rc == 2 and says in err and str(f) in err and err.count("\n") == 1, err
    assert not o.exists()


@pytest.mark.parametrize("argv", [
    ["mpy", "{afile}/sub"],
    ["dist", "{afile}/sub"],
    ["gap-check", "--small", "--keep", "{afile}/sub"],
])
def test_commands_that_only_write_name_the_path_they_cannot_write(argv, tmp_path, capsys):
    (tmp_path / "afile").write_text("a plain file, not a directory\n")
    argv = [a.format(afile=tmp_path / "afile") for a in argv]
    rc, out, err = run_front_door(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and err.startswith("error: ") and str(tmp_path / "afile") in err, err


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A log and the model `gap --export` wrote for it; replay runs on them (in the real VM)."""
    d = tmp_path_factory.mktemp("replay")
    _gap_log(d / "log.csv")
    assert front_door(["gap", str(d / "log.csv"), "--json", str(d / "gap.json"), "--quiet",
                       "--export", str(d / "model.json")]) == 0
    assert front_door(["replay", str(d / "model.json"), str(d / "log.csv"), "--json", str(d / "r.json")]) == 0
    _strict((d / "r.json").read_text())
    return d


# damage that can never leave a usable file (replay's valid runs are slow: the VM replays the log)
REPLAY_LOG = [(k, s) for k in ("delete_cell", "big", "nan", "nul", "latin1") for s in SEEDS] + \
    [(k, 0) for k in ("utf16", "garbage", "empty", "header_only")]
REPLAY_MODEL = [(k, 0) for k in ("utf16", "garbage", "empty", "nul")] + [("cut", s) for s in SEEDS] + \
    [("list", 0), ("number", 0), ("no-device", 0)]


@pytest.mark.parametrize("which,kind,seed", [("log",) + c for c in REPLAY_LOG] + [("model",) + c for c in REPLAY_MODEL])
def test_replay_damaged_input(which, kind, seed, exported, tmp_path, capsys):
    log, model = tmp_path / "log.csv", tmp_path / "model.json"
    log.write_bytes((exported / "log.csv").read_bytes())
    model.write_bytes((exported / "model.json").read_bytes())
    f = log if which == "log" else model
    rng = random.Random(seed * 31 + len(kind))
    if kind == "cut":
        b = f.read_bytes()
        f.write_bytes(b[:rng.randrange(1, len(b) - 3)])
    elif kind in ("list", "number", "no-device"):
        f.write_text({"list": "[1, 2]", "number": "7", "no-device": '{"t0_c": 25}'}[kind])
    elif kind == "nul" and which == "model":
        b = f.read_bytes()
        f.write_bytes(b[:5] + b"\x00" + b[5:])
    else:
        f.write_bytes(damage(kind, f.read_bytes(), rng)[0])
    o = tmp_path / "r.json"
    rc, out, err = run_front_door(["replay", str(model), str(log), "--json", str(o)], capsys)
    check_outcome(rc, out, err, f, [o], need_line=which == "log" and kind not in ("garbage", "empty", "header_only"))
    assert rc == 2


@pytest.mark.parametrize("model,says", [
    (b"", "not valid JSON"),
    (b"\xff\xfe{", "not UTF-8"),
    (b"[1, 2]", "no 'store' section"),
    (b'{"store": {"values": [1, 2]}}', "no 'store' section"),
    (b'{"store": {"values": [1, 2], "frac": [0, 99]}}', "frac[1] = 99"),
    (b'{"store": {"values": [1.5], "frac": [0]}}', "not an integer"),
    (b'{"store": {"values": "abc", "frac": [0]}}', "values must be a list"),
])
def test_store_put_refuses_a_bad_model(model, says, tmp_path, capsys):
    from tempcomp.store import Store

    p = str(tmp_path / "cal.bin")
    Store(p).save("gyro", (1, 2, 3))
    before = open(p, "rb").read()
    m = tmp_path / "model.json"
    m.write_bytes(model)
    rc, out, err = run_front_door(["store", "put", p, str(m), "--name", "aug"], capsys)
    assert rc == 2 and err.count("\n") == 1 and says in err and str(m) in err, err
    assert open(p, "rb").read() == before  # the store is unchanged


@pytest.mark.parametrize("tool", ["fit", "gap"])
def test_a_digit_grouping_underscore_is_not_a_number(tool, tmp_path, capsys):
    # float('124_956') is 124956 in Python: in a log it is a damaged '124.956' (a flipped byte,
    # found by test_damaged_input at TEMPCOMP_SEED=51), so every reader refuses it by line
    if tool == "fit":
        text = _an12760_csv()
        argv = ["fit", "an12760", "{f}", "--json", "{o}"]
    else:
        _gap_log(tmp_path / "src.csv")
        text = (tmp_path / "src.csv").read_text()
        argv = ["gap", "{f}", "--json", "{o}"]
    lines = text.splitlines(True)
    k = next(i for i in range(1, len(lines)) if "." in lines[i])
    lines[k] = lines[k].replace(".", "_", 1)
    (tmp_path / "d.csv").write_text("".join(lines))
    argv = [a.format(f=tmp_path / "d.csv", o=tmp_path / "o.json") for a in argv]
    rc, out, err = run_front_door(argv, capsys)
    assert rc == 2 and "Traceback" not in err, err
    assert err.count("\n") == 1 and "line %d" % (k + 1) in err and "not a number" in err, err
    assert not (tmp_path / "o.json").exists()
