"""Convert the real logs in ../shared/data (see its README) to the gap tool's CSV schema,
each split into a training log and a withheld log. The source files are read, never copied
or changed.

    python -m tools.simgap.convert [--data DIR] [--out DIR]

DIR defaults: --data $TEMPCOMP_DATA or ../shared/data beside the repository root;
--out out/real. Writes:
  tofupilot_gyro_{train,withheld}.csv, tofupilot_accel_{train,withheld}.csv,
  pan_gyro_{train,withheld}.csv

Units: the logs hold physical values, not LSB, so out is written in mdps (gyro) or mg (accel)
and the header says so (`# out_unit:`); the tool reports in whatever out_unit says.

Splits (why these): a withheld log must be data the fit never saw that still lies inside the
training temperature range, or every effect is judged on extrapolation.
  - tofupilot: train = rows 0-6193 (cool 52 -> -17.6 degC, heat to 74 degC); withheld = rows
    6194-8399 (cool 74 -> 34 degC), a whole cooling segment covered by the heating ramp.
  - PAN: train = bursts 0-9 and 15-24; withheld = bursts 10-14 (about 20.5 -> 19 degC), a
    middle temperature band, since the test only cools.
"""
import csv
import io
import os
import sys

import numpy as np

from tools import REPO, hostio
from tools.hostio import HostError, number, read_text
from tools.simgap.logio import LIMIT, LogError, write_log

RAD_TO_MDPS = 180.0 / np.pi * 1000.0
STANDARD_G = 9.80665          # m/s^2 per g (definition); local g is absorbed by the fit
TOFU_REL = os.path.join("tofupilot-imu-thermal", "imu_raw_data.csv")
PAN_REL = os.path.join("pan-cubesat-tvac", "TVCtest3_7_20.csv")
TOFU_SPLIT = 6194             # first row of the last cooling segment (data README)
PAN_BURST = 250
PAN_HELD_BURSTS = range(10, 15)



def default_data_dir():
    """$TEMPCOMP_DATA, else the data directory beside the repository (../shared/data)."""
    return os.environ.get("TEMPCOMP_DATA") or os.path.join(REPO, "..", "shared", "data")


def _read_table(path, delim, columns):
    """Named columns of a delimited text file as float arrays; errors name line and column."""
    try:
        text = read_text(path)
    except HostError as e:
        raise LogError(str(e)) from None
    reader = csv.reader(io.StringIO(text), delimiter=delim)
    rows = _rows(reader, path)
    header = [h.strip() for h in next(rows, [])]
    miss = [c for c in columns if c not in header]
    if miss:
        raise LogError(f"{path}: line 1: missing column(s) {', '.join(miss)}")
    idx = [header.index(c) for c in columns]
    out = [[] for _ in columns]
    for ln, row in enumerate(rows, start=2):
        if not row:
            continue
        if len(row) != len(header):   # a split or lost field shifts every column after it
            raise LogError(f"{path}: line {ln}: {len(row)} fields, header has {len(header)}")
        for k, i in enumerate(idx):
            cell = row[i]
            try:
                v = number(cell)
            except ValueError:
                raise LogError(f"{path}: line {ln}, column {i + 1} ({columns[k]}): "
                               f"not a number: {cell!r}") from None
            if not abs(v) < LIMIT:  # NaN, inf, or a value no logger writes
                raise LogError(f"{path}: line {ln}, column {i + 1} ({columns[k]}): "
                               f"{cell!r} is not a finite reading (|value| < {LIMIT:g})")
            out[k].append(v)
    if not out[0]:
        raise LogError(f"{path}: no data rows")
    return {c: np.asarray(v) for c, v in zip(columns, out)}


def _rows(reader, path):
    """The reader's rows; a line the csv module refuses (a stray carriage return or NUL inside a
    field) becomes a one-line LogError naming that line, not a traceback."""
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as e:
            raise LogError(f"{path}: line {reader.line_num}: unreadable: {e}") from None
        yield row


def tofupilot(path):
    """(gyro columns, accel columns, meta) for the whole tofupilot log."""
    cols = ["imu.gyro.x", "imu.gyro.y", "imu.gyro.z", "imu.acc.x", "imu.acc.y", "imu.acc.z",
            "imu.temperature"]
    d = _read_table(path, "\t", cols)
    n = len(d["imu.temperature"])
    t = np.arange(n, dtype=float)   # the timestamps span 4.2 s for a 90 degC profile
    zeros = np.zeros(n)
    g = {"time_s": t, "temp_c": d["imu.temperature"]}
    gyro = dict(g, out_x=d["imu.gyro.x"] * RAD_TO_MDPS, out_y=d["imu.gyro.y"] * RAD_TO_MDPS,
                out_z=d["imu.gyro.z"] * RAD_TO_MDPS, ref_x=zeros, ref_y=zeros, ref_z=zeros)
    # The gyro sees gravity along -z too; as the orientation never changes it is a constant.
    gyro.update(acc_x=zeros, acc_y=zeros, acc_z=-np.ones(n))
    acc = dict(g, out_x=d["imu.acc.x"] / STANDARD_G * 1000, out_y=d["imu.acc.y"] / STANDARD_G * 1000,
               out_z=d["imu.acc.z"] / STANDARD_G * 1000, ref_x=zeros, ref_y=zeros,
               ref_z=-np.ones(n))
    meta = {"source": "tofupilot/examples@fc190f7 imu_raw_data.csv (provenance unconfirmed)",
            "time": "row index, not seconds (the timestamp column spans 4.2 s)",
            "power_on_s": "0"}
    return gyro, acc, meta


def pan(path):
    cols = ["time (ms)", "gyrox rad/s", "gyroy rad/s", "gyroz rad/s", "temp"]
    d = _read_table(path, ",", cols)
    raw = d["temp"].astype(np.int64)
    signed = ((raw + 2 ** 15) % 2 ** 16) - 2 ** 15      # the word is an int16
    temp = 25.0 + signed / 256.0                          # LSM6DSM: 256 LSB/degC, 0 at 25 degC
    n = len(temp)
    zeros = np.zeros(n)
    gyro = {"time_s": d["time (ms)"] / 1000.0, "temp_c": temp,
            "out_x": d["gyrox rad/s"] * RAD_TO_MDPS, "out_y": d["gyroy rad/s"] * RAD_TO_MDPS,
            "out_z": d["gyroz rad/s"] * RAD_TO_MDPS, "ref_x": zeros, "ref_y": zeros, "ref_z": zeros}
    meta = {"source": "pathfinder-for-autonomous-navigation/psim@91d70ad TVCtest3_7_20.csv (LSM6DSM)",
            "power_on_s": "0"}
    return gyro, meta


def _split(cols, mask):
    return {k: v[mask] for k, v in cols.items()}, {k: v[~mask] for k, v in cols.items()}


def convert(data_dir, out_dir):
    """Write all converted logs; returns {name: (train path, withheld path)}."""
    gyro, acc, meta = tofupilot(os.path.join(data_dir, TOFU_REL))
    pg, pmeta = pan(os.path.join(data_dir, PAN_REL))  # every input read before anything is written
    os.makedirs(out_dir, exist_ok=True)
    done = {}
    train = np.arange(len(gyro["time_s"])) < TOFU_SPLIT
    for name, cols, sensor, ref_unit, unit in (("tofupilot_gyro", gyro, "gyro", "dps", "mdps"),
                                               ("tofupilot_accel", acc, "accel", "g", "mg")):
        m = dict(meta, sensor=sensor, ref_unit=ref_unit, out_unit=unit)
        done[name] = _write_pair(out_dir, name, *_split(cols, train), m)
    burst = np.arange(len(pg["time_s"])) // PAN_BURST
    train = ~np.isin(burst, list(PAN_HELD_BURSTS))
    m = dict(pmeta, sensor="gyro", ref_unit="dps", out_unit="mdps")
    done["pan_gyro"] = _write_pair(out_dir, "pan_gyro", *_split(pg, train), m)
    return done


def _write_pair(out_dir, name, train, held, meta):
    tp = os.path.join(out_dir, f"{name}_train.csv")
    wp = os.path.join(out_dir, f"{name}_withheld.csv")
    write_log(tp, train, meta)
    write_log(wp, held, meta)
    return tp, wp


def main(argv=None):
    ap = hostio.Parser(prog="python -m tools.simgap.convert")
    ap.add_argument("--data", default=default_data_dir())
    ap.add_argument("--out", default=os.path.join("out", "real"))
    a = ap.parse_args(argv)
    try:
        done = convert(a.data, a.out)
    except LogError as e:
        return hostio.fail(e)
    except OSError as e:
        return hostio.fail(f"{e.filename or a.out}: cannot write: {e.strerror}")
    for name, (tp, wp) in done.items():
        print(f"{name}: {tp} {wp}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
