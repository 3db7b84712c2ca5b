"""lib/tempcomp/augment.py: every term on, in the real 32-bit MicroPython VM under heap_lock
(an intermediate beyond the small-int range would allocate and fail there), against the
float64 reference in tools/simgap/devmodel.py, and bit-identical to the same code on CPython."""
import numpy as np
import pytest
import seeds
from augsynth import OUT_SCALE, every_term_model, inputs

from tempcomp import augment
from tools.simgap import devmodel, replay


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
    inp, F = inputs(m, seed=seeds.seed("augment_device/every_term"))
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
    rng = np.random.default_rng(seeds.seed("augment_device"))
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
    inp, _ = inputs(m, n=200, seed=seeds.seed("augment_device/n200"))
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


def test_a_power_on_mid_log_restarts_filters_and_uptime_like_the_reference():
    m = every_term_model()
    inp, _ = inputs(m, n=1200, seed=seeds.seed("augment_device_inputs"))
    inp["starts"] = np.array([700])
    inp["dt_ms"][700] = 0
    F = devmodel.features(m, inp)
    assert F[700, 6] == 0 and F[699, 6] > 600  # uptime back to 0 at the power-on
    out, info = replay.run_device(m, inp)
    assert info["heap_locked"] and info["power_ons"] == 1
    err = np.abs(out - devmodel.compensate(m, inp, F) * OUT_SCALE)
    assert err.max() <= 1.5
    # without the power-on the board's filters would carry on: the outputs differ after it
    inp2 = dict(inp, starts=np.array([], int))
    out2, _ = replay.run_device(m, inp2)
    assert np.array_equal(out2[:700], out[:700]) and not np.array_equal(out2[700:], out[700:])
