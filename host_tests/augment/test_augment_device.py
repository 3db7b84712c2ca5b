"""lib/tempcomp/augment.py: every term on, in the real 32-bit MicroPython VM under heap_lock
(an intermediate beyond the small-int range would allocate and fail there), against the
float64 reference in tools/simgap/devmodel.py, and bit-identical to the same code on CPython."""
import numpy as np
import pytest

from tempcomp import augment
from tools.simgap import devmodel, replay

OUT_SCALE = 100.0


def every_term_model():
    return {"t_lsb": 0.01, "t_off": 0.0, "raw_lsb": 1.0, "raw_range": [-32768, 32767],
            "out_scale": OUT_SCALE, "t0": 25.0, "t_cal": [0.0, 50.0], "supply_lsb": 0.001,
            "supply0": 3.3, "acc_lsb": 0.001,
            "offset": [[50, 4, -0.02], [-30, 2, 0.01], [10, -3, 0.015]],
            "sensitivity": [[16.4, 0.002], [16.0, -0.003], [16.2, 0.001]],
            "features": [{"kind": "dT"}, {"kind": "lag", "tau": 60.0, "bound": 10.0},
                         {"kind": "play", "width": 2.0}, {"kind": "play", "width": 1.0, "lag": 60.0},
                         {"kind": "drift_exp", "tau": 300.0}, {"kind": "drift_hyp", "tau": 200.0},
                         {"kind": "uptime", "bound": 20000.0}, {"kind": "supply", "bound": 0.5},
                         {"kind": "acc", "axis": 0, "bound": 2.0}, {"kind": "acc", "axis": 2, "bound": 2.0},
                         {"kind": "prod", "a": 1, "b": 0}, {"kind": "prod", "a": 1, "b": 1, "bound": 100.0},
                         {"kind": "prod", "a": 8, "b": 0}, {"kind": "lag", "tau": 900.0, "bound": 40.0}],
            "offset_terms": [[[1, 5.0], [2, 3.0], [4, 20.0], [6, 0.001], [10, 0.05], [11, 0.2]],
                             [[3, -4.0], [5, 8.0], [7, 30.0], [8, 2.0], [13, 1.5]],
                             [[9, -1.5], [12, 0.03]]],
            "gain_terms": [[[1, 0.002]], [[7, 0.01]], [[13, -0.001]]],
            "cross": [[[1, 0.01, 0.0001]], [[0, -0.005, 0.0]], [[0, 0.003, 0.0], [1, 0.002, -0.00005]]]}


def inputs(m, n=3000, seed=1, jitter=3):
    rng = np.random.default_rng(seed)
    t_s = np.arange(n) * 1.0
    T = 25 + 20 * np.sin(t_s / 400) + rng.normal(0, 0.05, n)
    ref = rng.uniform(-1500, 1500, (n, 3))
    inp = {"t": np.round(T / 0.01).astype(np.int64),
           "dt_ms": np.r_[0, np.full(n - 1, 1000) + rng.integers(-jitter, jitter + 1, n - 1)],
           "supply": np.round((3.3 + 0.2 * np.sin(t_s / 90)) / 0.001).astype(np.int64),
           "acc": np.round(rng.uniform(-1, 1, (n, 3)) / 0.001).astype(np.int64), "uptime0_ms": 0}
    F = devmodel.features(m, inp)
    inp["raw"] = np.round(devmodel.predict(m, inp, ref, F)).astype(np.int64)
    return inp, F


def cpython_run(m, inp):
    from array import array
    aug = augment.Augmented(m)
    aug.start(inp["uptime0_ms"])
    raw, out, acc = array("i", [0, 0, 0]), array("i", [0, 0, 0]), array("i", [0, 0, 0])
    res = np.zeros((len(inp["t"]), 3), np.int64)
    for i in range(len(inp["t"])):
        raw[0], raw[1], raw[2] = (int(v) for v in inp["raw"][i])
        acc[0], acc[1], acc[2] = (int(v) for v in inp["acc"][i])
        aug.apply(int(inp["t"][i]), raw, out, int(inp["dt_ms"][i]), int(inp["supply"][i]), acc)
        res[i] = out
    return res


@pytest.fixture(scope="module")
def every_term_run():
    m = every_term_model()
    inp, F = inputs(m)
    out, info = replay.run_device(m, inp)
    return m, inp, F, out, info


def test_every_term_allocates_nothing_in_the_vm(every_term_run):
    _, _, _, _, info = every_term_run
    assert info["heap_locked"], info
    assert info["allocated_per_sample"] == 0
    assert info["clamped"] == 0


def test_every_term_matches_float64_within_stated_lsb(every_term_run):
    m, inp, F, out, _ = every_term_run
    want = devmodel.compensate(m, inp, F) * OUT_SCALE
    err = out - want
    # the docstring's budget: the output's own rounding (0.5) plus the terms' fixed point
    assert np.max(np.abs(err)) <= 1.5, np.max(np.abs(err), axis=0)
    assert np.all(np.sqrt(np.mean(err ** 2, axis=0)) < 0.6)
    # and the terms matter: the base model alone is far off on the same codes
    base = devmodel.compensate(dict(m, features=[], offset_terms=None, gain_terms=None, cross=None), inp)
    assert np.sqrt(np.mean((base * OUT_SCALE - want) ** 2)) > 100


def test_cpython_gives_the_vm_bit_for_bit(every_term_run):
    m, inp, _, out, _ = every_term_run
    n = 400
    sub = {k: (v[:n] if isinstance(v, np.ndarray) else v) for k, v in inp.items()}
    assert np.array_equal(cpython_run(m, sub), out[:n])


def test_extreme_inputs_stay_small_ints_in_the_vm():
    # every input at the ends of its proven range (and beyond: clamped, counted), sudden
    # steps of the temperature across its whole input range, dt from 0 to hours
    m = every_term_model()
    n = 600
    rng = np.random.default_rng(7)
    aug = augment.Augmented(m)
    t_lo, t_hi = aug.comp.t_in
    inp = {"t": rng.choice([t_lo - 500, t_lo, t_hi, t_hi + 500, 2500], n),
           "dt_ms": rng.choice([0, 1, 999, 65535, 3600000, 10 ** 8], n),
           "raw": rng.choice([-32768, 32767, 0, -1], (n, 3)),
           "supply": rng.choice([0, 3300, 65535, -65535], n),
           "acc": rng.choice([-32768, 32767, 0, 2000], (n, 3)), "uptime0_ms": 0}
    out, info = replay.run_device(m, inp)
    assert info["heap_locked"], info
    assert info["allocated_per_sample"] == 0
    assert info["clamped"] > 0
    assert np.array_equal(cpython_run(m, inp), out)


def test_store_form_round_trips():
    m = every_term_model()
    v = augment.pack(m)
    back = augment.unpack(v)
    assert augment.pack(back) == v
    inp, _ = inputs(m, n=200)
    assert np.array_equal(cpython_run(back, inp), cpython_run(m, inp))


@pytest.mark.parametrize("change, words", [
    ({"features": [{"kind": "lag", "tau": -1.0}]}, "time constant must be positive"),
    ({"features": [{"kind": "wobble"}]}, "unknown kind"),
    ({"features": [{"kind": "prod", "a": 0, "b": 1}]}, "must come before it"),
    ({"gain_terms": [[[1, 0.5]], [], []]}, "sensitivity terms reach"),
    ({"cross": [[[0, 0.01, 0.0]], [], []]}, "names axis"),
    ({"t_lsb": 0.0}, "t_lsb must be positive"),
])
def test_bad_models_are_refused_by_name(change, words):
    m = every_term_model()
    m.update(change)
    with pytest.raises(ValueError, match=words):
        augment.Augmented(m)
