"""The whole diagnosis of one training log (and optional withheld log): returns the JSON
contract as a dict, plus the arrays the plot needs.

Order matters for honesty: coverage and identifiability are checked first; the noise model
is estimated with the effects in; effects are chosen and judged under it on held-out segments
of the training log only; a datasheet bound may keep one out; only then is the withheld log
scored, once, with the chosen model, against the floor the noise model predicts there."""
import numpy as np
from scipy import stats

from . import augmented, coverage, noise, plausible, prep, uncertainty
from .effects import BY_NAME, CATALOGUE
from .fit import Problem, demean_runs
from .logio import AXES
from .select import STEP_NEEDS, Greedy, design_gaps, wander_needs
from .where import localise

RATIO_WARN = 1.5        # final RMS over the model floor above which the residual is unexplained
BOOT_REPS = 300         # block-bootstrap replicates of every shrink and final RMS interval
COVERED_MIN = 0.95      # fraction of withheld rows inside the training coverage
QUANT_WARN = 1.0        # output step over the noise floor above which quantisation is reported
MAX_ROWS = 30_000       # longer logs are diagnosed on every k-th row (rows.stride)
TOB_T = 5.0             # t (effective samples) of a constant shift on a separate power-on
TOB_GAIN = 0.2          # ... and removing it must cut the withheld RMS by 20 %
SPLIT_BLOCKS = 20       # the withheld log's covered rows in this many contiguous blocks, A and
                        # B alternating: each half holds 10 blocks spread over the whole log,
                        # so both see its temperature programme at 1/20 of its length
MIN_CONFIRM_ROWS = 50   # half A shorter than this confirms nothing
STEP_ONSETS = 48        # onsets of the unlogged step tried on half A (_withheld_confirm.step_rival)


def _rms(v):
    return float(np.sqrt(np.mean(v ** 2))) if len(v) else float("nan")


def _per_axis(values, axes=range(3)):
    return {AXES[a]: float(values[a]) for a in axes}


def _warn(code, message, **kw):
    return dict({"code": code, "message": message}, **kw)


def _thin(log):
    """Every k-th row of a log longer than MAX_ROWS (k = ceil(n / MAX_ROWS)), and k. A
    temperature log's effects live over minutes; 30,000 rows resolve them, thinning keeps the
    noise model's family (white stays white, a walk's increments add), and the fit's cost and
    memory stay bounded (1 M + 1 M rows in about a minute on one core, docs/simgap.md)."""
    if log is None or len(log) <= MAX_ROWS:
        return log, 1
    k = int(np.ceil(len(log) / MAX_ROWS))
    return log.subset(slice(None, None, k)), k


def _withheld_split(prob, withheld, inside):
    """Half A (confirms) and half B (scores) of the withheld log's covered rows (inside:
    coverage.covered): SPLIT_BLOCKS contiguous blocks alternating A, B, A, ... None when the
    withheld log lies outside the training coverage (it then decides nothing)."""
    pw = prob.withheld
    if float(np.mean(inside)) < COVERED_MIN:
        return None
    idx = np.flatnonzero(pw.mask & inside)
    if len(idx) < 2 * MIN_CONFIRM_ROWS:
        return None
    block = int(np.ceil(len(idx) / SPLIT_BLOCKS))
    blk = np.arange(len(idx)) // block
    a = np.zeros(len(withheld), bool)
    b = np.zeros(len(withheld), bool)
    a[idx[blk % 2 == 0]] = True
    b[idx[blk % 2 == 1]] = True
    bid = np.full(len(withheld), -1)
    bid[idx] = blk
    return {"a": a, "b": b, "block_id": bid, "block_rows": block}


def _withheld_confirm(prob, g, withheld, split):
    """The p-value stage B's _confirm combines with the training one: on half A of the
    withheld log, the predictive log-likelihood of the model with the effect against the model
    without it, each with its coefficients frozen from the training fit under its own noise
    model (g.noise_for, as stage B pairs them), its one-step innovations by the Kalman filter
    (noise.concentrated_loglik over A's rows, half B's blocks between them gaps that
    noise.restarts bridges or restarts as it does any log's, a free level at each restart
    when the bias walks; each run's mean removed when the withheld log is its own power-on, the constant a
    user captures at start-up). The per-row log-likelihood differences d have mean <= 0 when
    the effect does not predict the repeat; the test is one-sided normal on their sum with a
    HAC variance, sum((d - mean d)^2) x their integrated autocorrelation time."""
    pw = prob.withheld
    ia = np.flatnonzero(split["a"])
    run = (withheld.run if withheld.run is not None else np.zeros(len(withheld), int))[ia]
    bid = split["block_id"][ia]
    seg = np.flatnonzero(np.r_[True, (np.diff(bid) != 0) | (np.diff(run) != 0)])
    t = withheld.t[ia]
    separate = "power_on_s" not in withheld.meta

    def row_ll(r, m):
        """Per-row predictive log-likelihood on A's rows of a withheld residual r under m."""
        r = r[ia]
        if separate:
            r = demean_runs(r, run)
        # Half B's rows between two blocks of A are a gap, bridged or restarted by the rule
        # every log's gaps follow (noise.restarts: restarted where the walk moves by more
        # than the white sigma over it, or the Gauss-Markov term forgets).
        starts = noise.restarts(t, prob.ctx.dt, seg, m)
        _, s2, u = noise.concentrated_loglik(r, m, starts)
        return -0.5 * (np.log(2 * np.pi * s2) + u * u / s2)

    def ll_rows(a, blocks):
        m = g.noise_for(a, blocks)["model"]
        return row_ll(prob.full_residual(pw, a, blocks, model=m), m)

    def one_sided_p(d):
        """p of sum(d) > 0, d the per-row log-likelihood differences (HAC variance)."""
        dc = d - np.mean(d)
        var = float(np.dot(dc, dc)) * noise.autocorr_time(dc)
        if not var > 0:
            return None
        return float(stats.norm.sf(float(np.sum(d)) / np.sqrt(var)))

    def confirm(a, without, with_):
        if len(ia) < MIN_CONFIRM_ROWS:
            return None
        return one_sided_p(ll_rows(a, with_) - ll_rows(a, without))

    def step_rival(a, effect_model, step_model):
        """One-sided p that the effect (effect_model: the others plus it, fitted on training
        without the step) predicts half A better than the unlogged step it lost to on the
        training log (step_model: the others plus the step, its time constant and size
        frozen from training) moved to the time that suits half A best. The step's cause
        happens at its own time in each log (it is not tied to the power-on, or it would be
        a warm-up), with the same size and settling: so its best onset on A - anywhere in
        the middle of the log, as the training grid allows, or wholly outside it - is the
        strongest form of that explanation, and the effect, frozen, must beat it. The onset
        is cross-fitted (each of two interleaved halves of A's blocks scored at the onset the
        other half likes best), so that the step's one free number is judged on rows that did
        not choose it, as the effect's are. Per-row log-likelihood differences as in confirm
        (HAC variance)."""
        if len(ia) < MIN_CONFIRM_ROWS:
            return None
        name, shape = step_model[-1]
        tau = shape[1]
        col = BY_NAME[name].columns
        size = float(prob.coefficients(a, step_model)[1][-1][2][0])
        m = g.noise_for(a, step_model)["model"]
        r0 = prob.full_residual(pw, a, step_model, model=m) + size * col(prob.ctx, pw, shape, a)[:, 0]

        # Onsets as the training grid allows them (effects.UnloggedStep: clear of the log's
        # ends, where a step would be a warm-up or nothing), and the step wholly before
        # the log (a constant) or after it (nothing).
        t_lo, t_hi = pw.log.t[0], pw.log.t[-1]
        span = t_hi - t_lo
        edge = BY_NAME[name].EDGE
        onsets = np.r_[t_lo - 50.0 * tau, np.linspace(t_lo + edge * span, t_hi - edge * span, STEP_ONSETS),
                       t_hi + 1.0]
        L = np.array([row_ll(r0 - size * col(prob.ctx, pw, (float(t1), tau), a)[:, 0], m)
                      for t1 in onsets])
        # Cross-fitted: A's blocks taken alternately as two halves, each half's rows scored at
        # the onset the other half likes best - an onset chosen on the rows it is scored on
        # would win by its own choice (the maximum over 50 onsets of a noisy sum).
        h = (bid // 2) % 2 == 0
        best = np.where(h, L[int(np.argmax(L[:, ~h].sum(1)))], L[int(np.argmax(L[:, h].sum(1)))])
        return one_sided_p(ll_rows(a, effect_model) - best)

    return confirm, step_rival


def diagnose(train, withheld=None, model=None):
    n_train, n_held = len(train), len(withheld) if withheld is not None else 0
    train, k_train = _thin(train)
    withheld, k_held = _thin(withheld)
    prob = Problem(train, withheld, model)
    ctx = prob.ctx
    warnings = []
    q_t = prep.output_step(train)
    base_t = np.column_stack([prob.full_residual(prob.train, a, []) for a in range(3)])
    sigma_t = prep.noise_floor(base_t, train, prob.train.mask, q_t)

    # 1. Identifiability of the base model on the training log.
    if model is None:
        for a in range(3):
            keep, why = ctx.base[a]
            if not (keep[1] and keep[2]):
                warnings.append(_warn(
                    "narrow_temperature_span",
                    f"the training log spans {ctx.tmax - ctx.tmin:.3g} degC "
                    f"({ctx.tmin:.3g}..{ctx.tmax:.3g}): {why[0]}; those parameters are fixed, "
                    "not fitted, and no temperature effect can be judged. Log a ramp over the "
                    "operating range to identify them.", axis=AXES[a], span_c=ctx.tmax - ctx.tmin))
                break

    # 2. Choose effects under the noise model on held-out segments of the training log.
    g = Greedy(prob, sigma_t)
    inside = coverage.covered(train, withheld) if withheld is not None else None
    split = _withheld_split(prob, withheld, inside) if withheld is not None else None
    if split is not None:
        # An effect stage B refuses only for the wander's Bartlett scale goes to half A of the
        # withheld log (Greedy._confirm); half B alone then scores whatever A confirmed.
        g.confirm, g.step_rival = _withheld_confirm(prob, g, withheld, split)
    g.run()
    g.refine()
    g.swap()
    g.reshape()
    pruned = g.prune()
    g.unlogged()

    # 3. Plausibility: every size outside the table is reported; only a datasheet bound on
    #    that coefficient alone keeps the effect out of the verdict.
    implausible = []
    for a in range(3):
        seen = set()
        while g.state[a]:
            bad = [b for b in plausible.check(prob, a, g.state[a]) if b[0] not in seen]
            if not bad:
                break
            name, size, limit, unit, basis, veto = max(bad, key=lambda b: (b[5], b[1] / b[2]))
            seen.add(name)
            if veto:
                g.state[a] = [(n, s) for n, s in g.state[a] if n != name]
            implausible.append({"effect": name, "axis": AXES[a], "size": size, "limit": limit,
                                "unit": unit, "basis": basis, "kept_out": bool(veto)})
            warnings.append(_warn(
                "implausible_coefficient",
                f"{name} on {AXES[a]} fitted {size:.3g} {unit}, beyond the {limit:g} {unit} a "
                f"{ctx.sensor} shows ({basis}); "
                + ("kept out of the verdict: a datasheet bound" if veto else
                   "kept: the bound is a rule of thumb, not a datasheet limit - check the set-up"),
                effect=name, axis=AXES[a], size=size, limit=limit, unit=unit))
    g.finalise()
    order = []
    for s in g.steps:
        if s["chosen"] and s["chosen"] not in order and any(
                n == s["chosen"] for a in range(3) for n, _ in g.state[a]):
            order.append(s["chosen"])
    for a in range(3):      # an effect that came in by a swap (Greedy.swap) was never a step's winner
        for n, _ in g.state[a]:
            if n not in order:
                order.append(n)
    verdict = list(order)

    # 4. Coverage of the withheld log, then its one scoring (on half B alone when half A
    #    confirmed an effect: split is None when the withheld log lies outside the coverage).
    on_b = split is not None and (any(c["confirmed"] for c in g.confirmations)
                                  or any(c["kept"] for c in g.step_rivals)
                                  or any(c["kept"] for c in g.borrow_checks))
    cov = {"train": coverage.describe(train)}
    extras = {"prob": prob, "base_train": base_t, "greedy": g}
    tob_shift = {}
    withheld_walk = {}
    not_confirmed = []
    if withheld is not None:
        pw = prob.withheld
        cov["withheld"] = coverage.describe(withheld)
        frac = float(np.mean(inside))
        cov["withheld_covered_fraction"] = frac
        cov["differences"] = coverage.differences(cov["train"], cov["withheld"])
        q_w = prep.output_step(withheld)
        base_w0 = np.column_stack([prob.full_residual(pw, a, []) for a in range(3)])
        sigma = prep.noise_floor(base_w0, withheld, pw.mask, q_w)
        outside = frac < COVERED_MIN
        if outside:
            w = cov["withheld"]
            warnings.append(_warn(
                "withheld_outside_training",
                f"{100 * (1 - frac):.0f} % of the withheld log lies outside what the training log "
                f"covers (withheld {w['temp_c'][0]:.3g}..{w['temp_c'][1]:.3g} degC, training "
                f"{ctx.tmin:.3g}..{ctx.tmax:.3g} degC, or inputs outside the training range); "
                "it is scored on the covered rows only and no effect rests on it",
                covered_fraction=frac))
        rows = pw.mask & inside
        if on_b:
            # Half A confirmed an effect: the final residual, the shrinks and the veto come
            # from half B alone, which chose nothing.
            rows = rows & split["b"]
        if rows.sum() < 50:
            rows = pw.mask.copy()   # nothing covered: report on all rows, flagged below
        source = f"withheld log {withheld.name}" + (
            f" ({int(rows.sum())} covered rows)" if outside else "") + (
            f" (half B: {int(rows.sum())} rows in {SPLIT_BLOCKS // 2} blocks; half A confirmed "
            "an effect)" if on_b else "")
        # A separate power-on (no power_on_s) starts from its own bias: on an axis whose
        # bias wanders, its level is unknowable, so every model is scored with each withheld
        # run's mean removed (a constant captured at start-up), and so is the floor.
        separate = "power_on_s" not in withheld.meta
        wrun = (withheld.run if withheld.run is not None else np.zeros(len(withheld), int))[rows]
        def wanders_without(a, i):
            # Could a wandering bias have taken effect i's place? (its axis's noise model
            # without it wanders, even if the final one, with it in, does not)
            return not g.noise_for(a, g.state[a][:i] + g.state[a][i + 1:])["model"].is_white

        def axis_wanders(a):
            return not prob.noise[a].is_white or any(
                wanders_without(a, i) for i in range(len(g.state[a])))

        # The training log's noise model can miss a walk whose realisation there stayed
        # small (measured: wander rw_drift seed 182, z: the walk moved 0.5 LSB RMS over the
        # training log, 2.9 over the withheld one, from K = 0.022 LSB/sqrt(s)). Its own
        # power-on's residual says whether the withheld bias wandered: the same state-space
        # likelihood test as the training log's (a walk in only where it earns BIC's share).
        # A level that walked is as unknowable there as on an axis whose training bias
        # walks, so each run is scored with its own mean removed. The floor stays the
        # training noise model's: a walk read on the scored log itself must not hide the
        # unexplained part of it.
        if separate and not outside:
            st_w = prep.stretches(withheld.t[rows], wrun)
            for a in range(3):
                if axis_wanders(a):
                    continue
                r = prob.full_residual(pw, a, g.state[a], model=prob.noise[a])[rows]
                m_w, _ = noise.estimate(r, ctx.dt, st_w, sigma[a] ** 2)
                if m_w.walks:
                    withheld_walk[a] = m_w

        def demeaned(a):
            # each withheld run scored less its own mean: its level is unknowable
            return separate and (axis_wanders(a) or a in withheld_walk)

        dm = {a: demeaned(a) for a in range(3)}

        def scored(a, r):
            r = r[rows]
            if not dm[a]:
                return r
            return demean_runs(r, wrun)

        extras["scored"] = scored
        # The withheld log may veto, never add: an effect that makes the covered withheld
        # residual worse on its axis is taken out (reported in not_confirmed). What is left
        # is scored once. The model with the effect and the model without it are each fitted
        # under its own noise model (noise_for, as stage B pairs them and as finalise() would
        # fit what is left): without the effect, a walk may take its place and bend the other
        # effects' fits with it (measured: the full set's temp_quantization + hysteresis pair
        # at seed 1, y: without the staircase a walk of q/s2 0.06 took it and the loop's fit
        # under that walk left 43.9 LSB on the withheld log, where the same fit under the
        # staircase's noise model had shown 3.8 - and the effect was vetoed on that 3.8).
        if not outside:
            for a in range(3):
                final_wanders = not prob.noise[a].is_white
                while g.state[a]:
                    rf = scored(a, prob.full_residual(pw, a, g.state[a],
                                                      model=g.noise_for(a, g.state[a])["model"]))
                    full = _rms(rf)
                    worst = None
                    for i, (n, _) in enumerate(g.state[a]):
                        without = g.state[a][:i] + g.state[a][i + 1:]
                        # Each model under its own noise model, as it would be scored: without
                        # the effect the axis's noise model is re-fitted (finalise), and a walk
                        # that takes the effect's place changes the fit of what remains.
                        r0 = scored(a, prob.full_residual(pw, a, without,
                                                          model=g.noise_for(a, without)["model"]))
                        w = _rms(r0)
                        lo = None
                        if (final_wanders or wanders_without(a, i)) and w >= full:
                            # Under a wandering bias the training log alone cannot always
                            # tell an effect from the walk; the withheld log (a repeat) must
                            # confirm it: its shrink's 90 % interval (block bootstrap, block
                            # length from the noise model) must exclude 0.
                            lo = uncertainty.shrink_interval(
                                r0, rf, uncertainty.block_length(prob.noise[a], rf))[0]
                        bad = w < full or (lo is not None and lo <= 0)
                        if bad and (worst is None or w < worst[1]):
                            worst = (i, w, lo)
                    if worst is None:
                        break
                    n = g.state[a][worst[0]][0]
                    rec = {"effect": n, "axis": AXES[a], "withheld_rms_with": full,
                           "withheld_rms_without": worst[1]}
                    if worst[2] is not None and worst[1] >= full:
                        rec["reason"] = ("the bias wanders and the withheld shrink's 90 % interval "
                                         f"reaches {worst[2]:.3g}: not confirmed")
                    not_confirmed.append(rec)
                    del g.state[a][worst[0]]
            g.finalise()
            dm.update({a: demeaned(a) for a in range(3)})
            verdict[:] = [v for v in verdict if any(n == v for a in range(3) for n, _ in g.state[a])]
            order[:] = [v for v in order if v in verdict]
        base_w = np.column_stack([prob.full_residual(pw, a, []) for a in range(3)])
        score = {a: prob.full_residual(pw, a, g.state[a]) for a in range(3)}
        sim_only = [_rms(scored(a, base_w[:, a])) for a in range(3)]
        # Turn-on bias across logs: a withheld log from its own power-on(s) may sit at a
        # constant shift per axis and run, which a user captures at start-up: the mean of
        # the first 5 % (at least 50 rows) of each run, applied to the whole run.
        corr = {}
        if separate and not outside:
            for a in range(3):
                if any(n == "turn_on_bias" for n, _ in g.state[a]) or dm[a]:
                    continue      # each withheld run already gets its own constant
                r = score[a][rows]
                c = np.zeros_like(r)
                shifts = {}
                steady = True
                tau = noise.autocorr_time(r - np.mean(r))
                for run in np.unique(wrun):
                    sel = np.flatnonzero(wrun == run)
                    k = max(50, len(sel) // 20)
                    first, last = float(np.mean(r[sel[:k]])), float(np.mean(r[sel[-k:]]))
                    c[sel] = shifts[int(run)] = first
                    # A power-on's shift is constant: the end of the run must agree with its
                    # start (a random walk or a drift moves between them).
                    tol = max(0.25 * abs(first), 4 * sigma[a] / np.sqrt(k))
                    steady &= abs(last - first) < tol
                se = np.std(r - c) * np.sqrt(tau / len(r))
                t = float(np.sqrt(np.mean(c * c))) / max(se, 1e-300)
                # ... and what is left is noise-like: a wander that happened to sit at one
                # level leaves a residual that is still correlated.
                rest_ok = (_rms(r - c) < RATIO_WARN * sigma[a]
                           or noise.classify(r - c - np.mean(r - c), sigma[a])[0] == "white")
                if steady and rest_ok and t > TOB_T and _rms(r - c) < (1 - TOB_GAIN) * _rms(r):
                    corr[a] = c
                    tob_shift[a] = shifts
            if tob_shift and "turn_on_bias" not in verdict:
                verdict.append("turn_on_bias")
        final_resid = {a: scored(a, score[a]) - corr.get(a, 0.0) for a in range(3)}
        final = [_rms(final_resid[a]) for a in range(3)]
        # The floor a perfect model would still leave there: white (the withheld log's own
        # first differences) plus what the noise model's slow terms add over each run.
        floor = []
        wl = withheld
        dtt = ctx.dt
        for a in range(3):
            nm = prob.noise[a]
            sets = []
            tw = wl.t[rows]
            if separate:
                for run in np.unique(wrun):
                    sel = wrun == run
                    sets.append(((tw[sel] - tw[sel][0]) / dtt, dm[a]))
            else:
                ton = pw.ton[rows]
                sets.append((np.maximum(ton, 0) / dtt, False))
            slow = max(0.0, nm.floor_ms(sets) - nm.s2 * (1 - (1 / max(1, rows.sum()) if dm[a] else 0)))
            floor.append(float(np.sqrt(sigma[a] ** 2 + slow)))
        extras.update(base_withheld=base_w, score_withheld=score, withheld_rows=rows,
                      tob_shift=tob_shift, tob_corr=corr)
    else:
        sigma = sigma_t
        q_w = q_t
        source = f"held-out segments of the training log ({prob.nfold} contiguous blocks)"
        sim_only = [_rms(prob.evaluate(a, [], withheld=False)["cv"]) for a in range(3)]
        final = [_rms(g.cur[a]["cv"]) for a in range(3)]
        final_resid = {a: g.cur[a]["cv"] for a in range(3)}
        # Held-out one-step-ahead innovations: a perfect model leaves the innovation sd.
        floor = [float(sigma[a] if prob.noise[a].is_white else np.sqrt(g.cur[a]["s2"]))
                 for a in range(3)]
        outside = False

    # 5. What the residual is made of.
    for a in range(3):
        q = max(q_t[a], q_w[a])
        if q > QUANT_WARN * sigma[a]:
            warnings.append(_warn(
                "quantized_output",
                f"{AXES[a]} output comes in steps of {q:.4g} {train.unit} "
                f"({q / sigma[a]:.2g}x the noise floor): the floor includes the step's "
                f"{q / np.sqrt(12):.3g} {train.unit} RMS and outliers are judged against it",
                axis=AXES[a], step=float(q)))
    noise_kind = {}
    noise_json = {}
    tu = "row" if "row index" in train.meta.get("time", "") else "s"
    for a in range(3):
        nm = prob.noise[a]
        info = g.noise_info.get(a, {}).get("final")
        kind = noise.describe(nm, sigma_t[a])
        _, ratio_a = noise.classify(final_resid[a] - np.mean(final_resid[a]), sigma[a])
        noise_kind[AXES[a]] = {"kind": kind, "allan_ratio": ratio_a}
        noise_json[AXES[a]] = nm.to_json(train.unit, tu, info["allan"] if info else None,
                                         info["allan_fit"] if info else None, stride=k_train)
        noise_json[AXES[a]]["white_floor_train"] = float(sigma_t[a])
        if not nm.is_white:
            rw = noise_json[AXES[a]]["random_walk"]
            bi = noise_json[AXES[a]]["bias_instability"]
            parts = ([f"random walk K = {rw['K']:.3g} {rw['unit']}"] if rw else []) + \
                ([f"bias instability {bi['sigma']:.3g} {train.unit}, Tc {bi['tau_c']:.3g} {tu}"]
                 if bi else [])
            warnings.append(_warn(
                "correlated_noise",
                f"{AXES[a]}: the bias wanders - {', '.join(parts)} (Allan deviation of the final "
                f"residual at the longest averaging time {ratio_a:.2g}x white noise's); effects are "
                "fitted and judged under this noise model, and the floor includes what it adds",
                axis=AXES[a], kind=kind, allan_ratio=ratio_a))
        if a in withheld_walk:
            m_w = withheld_walk[a]
            k_w = float(np.sqrt(m_w.q / m_w.dt))
            noise_json[AXES[a]]["withheld_random_walk"] = {
                "K": k_w, "unit": f"{train.unit}/sqrt({tu})", "q_per_sample": float(m_w.q),
                "scored": "each withheld run less its own mean"}
            warnings.append(_warn(
                "correlated_noise",
                f"{AXES[a]}: the withheld log's bias wanders (random walk K = {k_w:.3g} "
                f"{train.unit}/sqrt({tu}) on its residual) where the training log's showed no "
                "wander: each withheld run is scored less its own mean; the floor stays the "
                "training noise model's. A longer training log, or several power-ons, would "
                "show whether the walk is the part's",
                axis=AXES[a], kind="random walk (withheld log)", allan_ratio=ratio_a))
    ratio = {AXES[a]: float(final[a] / floor[a]) if floor[a] > 0 else None for a in range(3)}
    ratio_white = {AXES[a]: float(final[a] / sigma[a]) if sigma[a] > 0 else None for a in range(3)}
    for a in range(3):
        if ratio[AXES[a]] is not None and ratio[AXES[a]] > RATIO_WARN:
            warnings.append(_warn(
                "unexplained_residual",
                f"{AXES[a]}: the final {'withheld ' if withheld is not None else 'held-out '}"
                f"RMS is {ratio[AXES[a]]:.2f}x the noise model's floor "
                f"({final[a]:.4g} vs {floor[a]:.4g} {train.unit}; white floor {sigma[a]:.4g})"
                + ("" if verdict else "; no effect in the catalogue explains it"),
                axis=AXES[a], ratio=ratio[AXES[a]]))
    # Intervals: the final RMS (and its ratio) by a block bootstrap whose block length comes
    # from the noise model.
    blocks_len = {a: uncertainty.block_length(prob.noise[a], final_resid[a]) for a in range(3)}
    extras["block_len"] = blocks_len
    final_ci = {a: uncertainty.rms_interval(final_resid[a], blocks_len[a]) for a in range(3)}

    # 6. Per-effect records and the waterfall (training held-out segments choose; the
    #    withheld figures are reported, never used to choose).
    effects = _effect_records(prob, g, verdict, withheld is not None and not outside, extras)
    waterfall = _waterfall(prob, g, order, sim_only, extras, tob_shift)
    confused, apart = g.confusions()
    gaps = design_gaps(prob, verdict, g.untried)
    seen = {frozenset(c["effects"]) for c in confused}
    not_ident = confused + [c for c in gaps if frozenset(c["effects"]) not in seen]
    # Effects a wandering bias explains about as well (stage B or the backward check).
    wander = {}
    for w in g.wander:
        if any(n == w["effect"] for n, _ in g.state[w["axis"]]):
            continue
        kind = "random_walk" if "random walk" in w["kind"] or w["kind"] == "white" else "bias_instability"
        key = (w["effect"], kind)
        e = wander.setdefault(key, {"effects": [w["effect"], kind], "axes": [],
                                    "needs": wander_needs(w["effect"]), "z": []})
        if AXES[w["axis"]] not in e["axes"]:
            e["axes"].append(AXES[w["axis"]])
            e["z"].append(round(float(w["z"]), 2))
    not_ident += list(wander.values())
    # Effects an offset step at an unlogged time explains as well (Greedy.unlogged).
    stepped = {}
    for w in g.stepped:
        e = stepped.setdefault(w["effect"], {"effects": [w["effect"], "unlogged_step"], "axes": [],
                                             "needs": STEP_NEEDS, "z": []})
        e["axes"].append(AXES[w["axis"]])
        e["z"].append(round(float(w["z"]), 2))
    not_ident += list(stepped.values())
    where = localise(prob.train, base_t, sigma_t, ctx)
    result = {
        "verdict": verdict,
        "effects": effects,
        "where": where,
        "final": {"withheld_rms": _per_axis(final),
                  "unexplained_rms": {AXES[a]: float(np.sqrt(max(0.0, final[a] ** 2 - floor[a] ** 2)))
                                      for a in range(3)},
                  "ratio_to_noise": ratio,
                  "ratio_to_white_floor": ratio_white,
                  "model_floor": _per_axis(floor),
                  "withheld_rms_interval": {AXES[a]: final_ci[a] for a in range(3)},
                  "ratio_to_noise_interval": {
                      AXES[a]: [v / floor[a] if v is not None and floor[a] > 0 else None
                                for v in final_ci[a]] for a in range(3)},
                  "interval": "90 %, stationary block bootstrap of the scored rows (block length "
                              "from the noise model)",
                  "block_length": {AXES[a]: blocks_len[a] for a in range(3)}},
        "sim_only": {"withheld_rms": _per_axis(sim_only)},
        "noise_floor": _per_axis(sigma),
        "model_floor": _per_axis(floor),
        "noise_model": noise_json,
        "noise_floor_train": _per_axis(sigma_t),
        "output_step": _per_axis(np.maximum(q_t, q_w)),
        "noise": noise_kind,
        "warnings": warnings,
        "coverage": cov,
        "implausible": implausible,
        "pruned": [{"effect": n, "axis": AXES[a], "z": z} for n, a, z in pruned],
        "joint": _joint_json(g),
        "borrow_checks": [dict(c, axis=AXES[c["axis"]]) for c in g.borrow_checks],
        "not_confirmed": not_confirmed,
        "not_identifiable": not_ident,
        "told_apart": apart,
        "untried": [{"name": n, "reason": r} for n, r in g.untried.items()],
        "waterfall": waterfall,
        "withheld_source": source,
        "withheld_split": _split_json(split, g, on_b),
        "selected_on": f"held-out segments of the training log ({prob.nfold} contiguous blocks)",
        "unit": train.unit,
        "sim": "given model" if model is not None else "fitted on the training log",
        "rows": {"train": n_train, "train_outliers": int((~prob.train.mask).sum()),
                 "withheld": n_held,
                 "withheld_outliers": int((~prob.withheld.mask).sum()) if withheld is not None else 0,
                 "stride": {"train": k_train, "withheld": k_held},
                 "used": {"train": len(train), "withheld": len(withheld) if withheld is not None else 0}},
    }
    model_json = augmented.build(prob, g.state, tob_shift)
    held = prob.withheld if withheld is not None else prob.train
    model_json["host_check"] = augmented.host_check(model_json, prob, held,
                                                    "withheld" if withheld is not None else "training")
    result["model"] = model_json
    return result, extras


def _joint_json(g):
    """Masking pairs the greedy search added together (Greedy._joint) and still in the model."""
    out = {}
    for j in g.joint:
        have = {n for n, _ in g.state[j["axis"]]}
        if not set(j["effects"]) <= have:
            continue
        e = out.setdefault(tuple(j["effects"]), {"effects": j["effects"], "axes": [], "z": [], "z_wander": []})
        e["axes"].append(AXES[j["axis"]])
        e["z"].append(round(j["z"], 2))
        e["z_wander"].append(round(j["z_wander"], 2))
    return list(out.values())


def _split_json(split, g, on_b):
    """The withheld log's halves: A confirms (Greedy._confirm), B scores when A confirmed
    anything (on_b), else the whole covered withheld log scores."""
    if split is None:
        return None
    return {"block_rows": split["block_rows"], "blocks": SPLIT_BLOCKS,
            "rows_a": int(split["a"].sum()), "rows_b": int(split["b"].sum()),
            "scored_on": "half B" if on_b else "whole",
            "confirmations": [dict(c, axis=AXES[c["axis"]]) for c in g.confirmations],
            "step_rivals": [dict(c, axis=AXES[c["axis"]]) for c in g.step_rivals]}


def _effect_records(prob, g, verdict, use_withheld, extras):
    """One record per effect tried. Held-out (training) figures are what chose it; withheld
    figures, when a covered withheld log exists, are the one score of the chosen model."""
    out = []
    rank = {n: i for i, n in enumerate(verdict)}
    state = {a: list(g.state[a]) for a in range(3)}
    rows = extras.get("withheld_rows")
    scored = extras.get("scored")
    for name in CATALOGUE:
        if name == "turn_on_bias" and extras.get("tob_shift"):
            corr = extras["tob_corr"]
            sw = extras["score_withheld"]
            before = {AXES[a]: _rms(sw[a][rows]) for a in range(3)}
            after = {AXES[a]: _rms(sw[a][rows] - corr.get(a, 0.0)) for a in range(3)}
            axes = [AXES[a] for a in corr]
            b2 = sum(before[a] ** 2 for a in axes)
            a2 = sum(after[a] ** 2 for a in axes)
            out.append({"name": name, "axes": axes, "withheld_rms_before": before,
                        "withheld_rms_after": after, "shrink": float(1 - np.sqrt(a2 / b2)),
                        "significant": True, "rank": rank[name], "scored_on": "withheld",
                        "source": "separate power-on(s) of the withheld log, captured at start-up",
                        "shift": {AXES[a]: v for a, v in extras["tob_shift"].items()},
                        "shape": {}, "t": {}})
            continue
        if name not in g.avail:
            continue
        rec = {a: g.record[(name, a)] for a in g.avail[name] if (name, a) in g.record}
        if not rec:
            continue
        added = [a for a in range(3) if any(n == name for n, _ in state[a])]
        axes = added or list(rec)
        hb = {a: rec[a]["rms_before"] for a in rec}
        ha = {a: rec[a]["rms_after"] for a in rec}
        before, after, scored_on = hb, ha, "heldout"
        rb, ra = {}, {}
        if use_withheld and added:
            before, after = {}, {}
            for a in rec:
                blocks = state[a]
                if any(n == name for n, _ in blocks):
                    without = [(n, s) for n, s in blocks if n != name]
                    with_ = blocks
                else:
                    without, with_ = blocks, blocks + [(name, rec[a]["shape"])]
                rb[a] = scored(a, prob.full_residual(prob.withheld, a, without))
                ra[a] = scored(a, prob.full_residual(prob.withheld, a, with_))
                before[a], after[a] = _rms(rb[a]), _rms(ra[a])
            scored_on = "withheld"
        b2 = sum(before[a] ** 2 for a in axes)
        a2 = sum(after[a] ** 2 for a in axes)
        hb2 = sum(hb[a] ** 2 for a in axes)
        ha2 = sum(ha[a] ** 2 for a in axes)
        ci = [None, None]
        if name in rank:
            if ra:
                bl = [a for a in axes if a in ra]
                bm = np.column_stack([rb[a] for a in bl])
                am = np.column_stack([ra[a] for a in bl])
            else:
                bl = [a for a in axes if "cv_before" in rec[a]]
                bm = np.column_stack([rec[a]["cv_before"] for a in bl]) if bl else None
                am = np.column_stack([rec[a]["res"]["cv"] for a in bl]) if bl else None
            if bl:
                L = max(extras["block_len"][a] for a in bl)
                ci = uncertainty.shrink_interval(bm, am, L)
        out.append({
            "name": name, "axes": [AXES[a] for a in axes],
            "shrink_interval": ci,
            "withheld_rms_before": _per_axis(before, rec),
            "withheld_rms_after": _per_axis(after, rec),
            "shrink": float(1 - np.sqrt(a2 / b2)) if b2 > 0 else 0.0,
            "scored_on": scored_on,
            "heldout_rms_before": _per_axis(hb, rec), "heldout_rms_after": _per_axis(ha, rec),
            "heldout_shrink": float(1 - np.sqrt(ha2 / hb2)) if hb2 > 0 else 0.0,
            "significant": name in rank,
            "rank": rank.get(name),
            "shape": {AXES[a]: _shape_str(v["shape"]) for a, v in rec.items()},
            "t": {AXES[a]: round(float(v["t"]), 2) for a, v in rec.items()},
            "p": {AXES[a]: float(v.get("p", np.nan)) for a, v in rec.items()},
            "autocorr_time": {AXES[a]: round(float(v.get("tau", 1.0)), 2) for a, v in rec.items()},
        })
    return out


def _waterfall(prob, g, order, sim_only, extras, tob_shift):
    """Per-axis scored RMS as the verdict's effects are added in order (final shapes)."""
    wf = [{"added": None, "withheld_rms": _per_axis(sim_only)}]
    rows = extras.get("withheld_rows")
    for k, name in enumerate(order):
        vals = dict(wf[-1]["withheld_rms"])
        for a in range(3):
            if not any(n == name for n, _ in g.state[a]):
                continue
            blocks = [(n, s) for n, s in g.state[a] if n in order[:k + 1]]
            if rows is not None:
                vals[AXES[a]] = _rms(extras["scored"](a, prob.full_residual(prob.withheld, a, blocks)))
            else:
                vals[AXES[a]] = _rms(prob.evaluate(a, blocks, withheld=False)["cv"])
        wf.append({"added": name, "withheld_rms": vals})
    if tob_shift:
        vals = dict(wf[-1]["withheld_rms"])
        for a, c in extras["tob_corr"].items():
            vals[AXES[a]] = _rms(extras["score_withheld"][a][rows] - c)
        wf.append({"added": "turn_on_bias", "withheld_rms": vals})
    return wf


def _shape_str(s):
    if isinstance(s, tuple) and isinstance(s[0], str):
        return f"{s[0]} tau={s[1]:.4g}s"
    if isinstance(s, tuple):   # hysteresis on a lagged temperature: (width, lag)
        return f"{float(s[0]):.4g} on lag tau={float(s[1]):.4g}s"
    if isinstance(s, float):
        return f"{s:.4g}"
    return str(s)
