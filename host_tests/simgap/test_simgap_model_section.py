"""The JSON `model` section (docs/simgap.md, its `model` section): evaluating the
exported numbers reproduces the fit's own predictions for every effect family, and a pure
quadratic log exports its true coefficients."""
import json

import numpy as np
import pytest
from seeds import seed
from simgap_synth import make

from tools.simgap import augmented
from tools.simgap.diagnose import diagnose
from tools.simgap.effects import EFFECTS
from tools.simgap.fit import Problem
from tools.simgap.logio import Log


def _rich_log(seed, n=1500):
    """Every optional column present and varying, so every family is available."""
    base = make(None, n=n, seed=seed)
    rng = np.random.default_rng([seed, 1])   # apart from make's stream
    faces = np.eye(3)[np.repeat(rng.integers(0, 3, n // 100 + 1), 100)[:n]]
    supply = np.repeat(rng.choice([3.0, 3.3, 3.6], n // 80 + 1), 80)[:n]
    run = np.repeat(np.arange(3), n // 3 + 1)[:n]
    temp = np.round(base.temp * 2) / 2            # a coarse reading: temp_quantization applies
    return Log("rich", base.t, temp, base.out, base.ref, {"sensor": "gyro"}, supply=supply,
               acc=faces, run=run)


@pytest.mark.parametrize("effect", [e for e in EFFECTS], ids=lambda e: e.name)
def test_exported_numbers_reproduce_the_fit(effect):
    train, held = _rich_log(seed("model_section/train")), _rich_log(seed("model_section/withheld"))
    prob = Problem(train, held)
    shape = effect.shapes(prob.ctx)[0]
    state = {a: [(effect.name, shape)] for a in range(3)}
    model = json.loads(json.dumps(augmented.build(prob, state)))   # through JSON, as a device gets it
    for a in range(3):
        want = prob.full_residual(prob.withheld, a, state[a])
        got = held.out[:, a] - augmented.predict(model, held, prob.withheld, a)
        if effect.per_run:   # a power-on the fit never saw: its own constant, captured at start
            for r in np.unique(held.run):
                got[held.run == r] -= got[held.run == r].mean()
        assert np.max(np.abs(got - want)) < 1e-6 * np.max(np.abs(held.out[:, a]))


def test_pure_quadratic_exports_its_coefficients():
    # simgap_synth.make: out = 50 + 4 dT - 0.02 dT^2 + 16 (1 + 1e-4 dT) ref, noise 2 LSB.
    res, _ = diagnose(make(None, n=3000, seed=seed("model_section/quadratic")),
                      make(None, n=2000, seed=seed("model_section/quadratic", 1)))
    m = res["model"]
    assert m["schema"] == "tempcomp.simgap.model/1" and m["t0_c"] == 25.0
    for ax in "xyz":
        assert m["axes"][ax]["effects"] == []
        o, s = m["base_only"][ax]["offset"], m["base_only"][ax]["sensitivity"]
        assert o == pytest.approx([50, 4, -0.02], abs=0.2) and o[2] == pytest.approx(-0.02, abs=2e-3)
        assert s[0] == pytest.approx(16, rel=1e-3) and s[1] == pytest.approx(16e-4, abs=3e-4)
        hc = m["host_check"]["rms"]
        assert hc["augmented"][ax] == pytest.approx(res["final"]["withheld_rms"][ax], rel=1e-9)
