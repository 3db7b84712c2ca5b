"""The noise model the diagnosis lives in, per axis (IEEE Std 952 / 1293 terms):

    residual = white (sigma^2 per sample; angle random walk N = sigma sqrt(dt) for a gyro's rate)
             + bias random walk (increment variance q per sample; rate random walk K = sqrt(q/dt))
             + bias instability as a first-order Gauss-Markov process (variance g2, correlation phi
               per sample, correlation time Tc = -dt / ln phi) where the data show one.

A rate ramp (Allan slope +1) is deterministic: a drift candidate, never noise.

Estimated two ways on the residual of the current model (effects in): the overlapping Allan
deviation (allantools, with its confidence intervals) fitted by weighted least squares - what
the report and the plot show, IEEE style - and the state-space likelihood, which scores
effects: white + random walk + AR(1) is an ARIMA(1,1,2) whose steady-state Kalman innovations
are a linear filter (scipy.signal.lfilter), so generalised least squares is ordinary least
squares on filtered columns, O(n k)."""
import allantools
import numpy as np
from scipy import optimize, stats
from scipy.signal import lfilter

TINY = 1e-280        # filtered values below this are flushed to zero (whiten)
MIN_BLOCKS = 8        # fewer independent blocks than this cannot support a finding
CI = 0.90             # confidence level of every interval the tool reports
TERM_GAIN = 3.0       # nats a noise term (random walk, Gauss-Markov) must add to the likelihood
                      # of the residual to be part of the model (~ BIC at 400 rows; a term
                      # that changes nothing is left out so the filter stays the identity)


def autocorr_time(x, c=5.0, max_frac=0.25):
    """Integrated autocorrelation time tau = 1 + 2 sum rho(k), summed over lags up to the
    first window W >= c tau(W) (Sokal's rule); 1 for white noise, n/... for a random walk."""
    x = np.asarray(x, float)
    n = x.size
    if n < 16:
        return 1.0
    x = x - x.mean()
    v = float(np.dot(x, x))
    if v == 0:
        return 1.0
    m = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, m)
    acf = np.fft.irfft(f * np.conj(f), m)[:n] / v
    tau = np.cumsum(2 * acf) - 1.0
    kmax = int(max_frac * n)
    for w in range(1, kmax):
        if w >= c * tau[w]:
            return float(max(1.0, tau[w]))
    return float(max(1.0, tau[kmax - 1]))


# ---------------------------------------------------------------- Allan deviation

def allan(x, dt=1.0):
    """Overlapping Allan deviation of a rate-like series at octave averaging times (allantools),
    with its 90 % confidence interval (chi-squared, equivalent degrees of freedom for white
    noise, allantools.edf_simple). Returns dict of arrays tau (s), m (samples), adev, lo, hi,
    edf; empty arrays for a series too short to average."""
    x = np.asarray(x, float)
    n = x.size
    if n < 16:
        e = np.zeros(0)
        return {"tau": e, "m": e, "adev": e, "lo": e, "hi": e, "edf": e}
    taus, adev, _, _ = allantools.oadev(x - x.mean(), rate=1.0 / dt, data_type="freq", taus="octave")
    m = np.round(np.asarray(taus) / dt)
    keep = (n // np.maximum(m, 1) >= 4) & (adev > 0)
    taus, adev, m = np.asarray(taus)[keep], np.asarray(adev)[keep], m[keep]
    edf = np.array([max(1.0, float(allantools.edf_simple(n, int(k), 0))) for k in m])
    lo, hi = np.empty_like(adev), np.empty_like(adev)
    for i, (d, e) in enumerate(zip(adev, edf)):
        lo[i], hi[i] = allantools.confidence_interval(d, e, ci=CI)
    return {"tau": taus, "m": m, "adev": adev, "lo": lo, "hi": hi, "edf": edf}


def gm_sum(phi, m):
    """S = sum_{i,j<m} phi^|i-j| and C = sum_{i<m<=j<2m} phi^(j-i): an AR(1)'s block-mean
    variance and adjacent-block covariance (times g2 / m^2)."""
    m = np.asarray(m, float)
    if phi <= 0:
        return m, np.zeros_like(m)
    pm = phi ** m
    S = m * (1 + phi) / (1 - phi) - 2 * phi * (1 - pm) / (1 - phi) ** 2
    C = phi * (1 - pm) ** 2 / (1 - phi) ** 2
    return S, C


def avar_terms(m, s2=0.0, q=0.0, g2=0.0, phi=0.0, ramp=0.0):
    """Allan variance at m samples of averaging of each term (discrete time, exact): white
    s2/m; random walk q (2 m^2 + 1) / (6 m); Gauss-Markov g2 (S - C) / m^2; ramp (per
    sample) ramp^2 m^2 / 2."""
    m = np.asarray(m, float)
    out = {"white": s2 / m, "random_walk": q * (2 * m * m + 1) / (6 * m)}
    S, C = gm_sum(phi, m) if g2 > 0 else (m, 0 * m)
    out["bias_instability"] = g2 * (S - C) / (m * m) if g2 > 0 else 0 * m
    out["rate_ramp"] = ramp ** 2 * m * m / 2
    return out


def fit_allan(ad, s2_floor=0.0):
    """Weighted least squares of the Allan variance on the IEEE terms: white, random walk, a
    Gauss-Markov term (correlation time on a grid between 2 samples and the longest averaging
    time) and a rate ramp, all non-negative (scipy nnls), weights from the equivalent degrees
    of freedom (var(avar) = 2 avar^2 / edf). Returns {s2, q, g2, phi, ramp} per sample."""
    m, av, edf = ad["m"], ad["adev"] ** 2, ad["edf"]
    if m.size < 3:
        return {"s2": float(np.mean(av)) if av.size else s2_floor, "q": 0.0, "g2": 0.0, "phi": 0.0,
                "ramp": 0.0}
    w = np.sqrt(edf / 2.0) / av          # 1 / sd of each avar estimate
    cols = [1.0 / m, (2 * m * m + 1) / (6 * m), m * m / 2]
    best = None
    for tc in [0.0] + list(np.geomspace(2.0, max(3.0, m[-1]), 12)):
        X = list(cols)
        phi = float(np.exp(-1.0 / tc)) if tc else 0.0
        if tc:
            S, C = gm_sum(phi, m)
            X.append((S - C) / (m * m))
        A = np.column_stack(X) * w[:, None]
        coef, rn = optimize.nnls(A, av * w)
        if best is None or rn < best[0] - 1e-12:
            best = (rn, coef, phi)
    _, c, phi = best
    g2 = float(c[3]) if len(c) > 3 else 0.0
    return {"s2": max(float(c[0]), s2_floor), "q": float(c[1]), "ramp": float(np.sqrt(c[2])),
            "g2": g2, "phi": phi if g2 > 0 else 0.0}


# ---------------------------------------------------------------- state-space noise model

class NoiseModel:
    """white s2 + random walk q + Gauss-Markov (g2, phi), per sample, in out units; dt in the
    log's time unit. `filter` gives the monic whitening filter of the steady-state Kalman
    innovations: u = lfilter(b, a, residual)."""

    def __init__(self, s2, q=0.0, g2=0.0, phi=0.0, dt=1.0):
        self.s2, self.q, self.dt = float(max(s2, 1e-300)), float(max(q, 0.0)), float(dt)
        self.g2 = float(max(g2, 0.0)) if phi > 0 else 0.0
        self.phi = float(phi) if self.g2 > 0 else 0.0
        self._filt = None

    @classmethod
    def white(cls, sigma, dt=1.0):
        return cls(sigma ** 2, dt=dt)

    @property
    def is_white(self):
        return self.q <= 0 and self.g2 <= 0

    @property
    def walks(self):
        return self.q > 0

    def key(self):
        return (self.s2, self.q, self.g2, self.phi)

    def filter(self):
        """(b, a, innovation variance): AR side b = (1 - L)^d (1 - phi L)^g, MA side a from the
        spectral factorisation of the autocovariance of b(L) x (an MA(d + g) process)."""
        if self._filt is None:
            self._filt = _whitening(self.s2, self.q, self.g2, self.phi)
        return self._filt

    def memory(self, tol=1e-3, cap=100_000):
        """Samples after which the whitening filter's impulse response has decayed below tol
        of its start (how far a held-out block's data reach into the rows after it)."""
        b, a, _ = self.filter()
        if len(a) == 1:
            return len(b) - 1
        r = np.abs(np.roots(a))
        rho = float(np.max(1.0 / r)) if r.size else 0.0    # largest pole of 1/a(L)
        if rho <= 0:
            return len(b)
        return int(min(cap, np.ceil(np.log(tol) / np.log(min(rho, 1 - 1e-12))) + len(b)))

    def floor_ms(self, ton_sets):
        """Expected mean square a perfect model would still leave, averaged over rows: for each
        (times from power-on in samples, remove_mean) set, white + random walk started at power-on
        + Gauss-Markov, with the set's own mean removed when remove_mean (a constant shift is
        captured at start-up). Sets longer than 2,000 rows use every k-th row."""
        tot, n = 0.0, 0
        for ton, demean in ton_sets:
            ton = np.asarray(ton, float)
            if ton.size == 0:
                continue
            k = max(1, ton.size // 2000)
            s = ton[::k]
            v = self.s2 * (1 - (1.0 / ton.size if demean else 0.0))
            if self.q > 0:
                # walk covariance q min(s_i, s_j): its diagonal's mean, less its mean
                v += self.q * (float(np.mean(s)) - (_mean_min(s) if demean else 0.0))
            if self.g2 > 0:
                v += self.g2 * (1.0 - (_mean_pow_gap(s, self.phi) if demean else 0.0))
            tot += v * ton.size
            n += ton.size
        return tot / n if n else self.s2

    def avar(self, m):
        t = avar_terms(m, self.s2, self.q, self.g2, self.phi)
        return t["white"] + t["random_walk"] + t["bias_instability"]

    def to_json(self, unit, time_unit, ad=None, fit=None, stride=1):
        """The `noise_model` JSON of one axis: each term in its IEEE unit and the averaging time
        where it dominates the fitted Allan deviation.

        stride k > 1: the model was estimated on every k-th row of the log (rows.stride), so
        its sample is k of the log's steps (dt = sample_period). Dropping rows leaves each
        row's white noise as it was (sigma is the log's own), while a walk's increments add
        over the k steps (q is per model sample; K and tau_c are physical either way). The
        angle/velocity random walk N = sigma sqrt(step) is the log's: read at its own step,
        dt / k, not at dt (that would overstate it sqrt(k) times)."""
        dt = self.dt
        step = dt / max(1, int(stride))
        tu = time_unit
        m = np.geomspace(1, max(2.0, ad["m"][-1] if ad is not None and ad["m"].size else 1e4), 200)
        terms = avar_terms(m, self.s2, self.q, self.g2, self.phi)
        tot = terms["white"] + terms["random_walk"] + terms["bias_instability"]

        def dom(name):
            share = terms[name] / tot
            i = int(np.argmax(share))
            return float(m[i] * dt) if share[i] > 0.5 else None

        out = {
            "white": {"sigma": float(np.sqrt(self.s2)), "unit": unit,
                      "N": float(np.sqrt(self.s2 * step)), "N_unit": f"{unit}*sqrt({tu})",
                      "read_at": float(dt), "dominates_to": _last_dom(m * dt, terms["white"] / tot)},
            "random_walk": None, "bias_instability": None,
            "averaging_time_unit": tu, "sample_period": float(dt), "stride": max(1, int(stride)),
            "log_sample_period": float(step), "method":
                "state-space likelihood (white + bias random walk + first-order Gauss-Markov), "
                "steady-state Kalman innovations"}
        if self.q > 0:
            out["random_walk"] = {"q_per_sample": float(self.q), "K": float(np.sqrt(self.q / dt)),
                                  "unit": f"{unit}/sqrt({tu})", "read_at": dom("random_walk"),
                                  "sigma_over_log": None}
        if self.g2 > 0:
            tc = -dt / np.log(self.phi)
            # IEEE 952: bias instability B is the flat Allan floor / 0.664; a Gauss-Markov
            # term's Allan deviation peaks at about 0.62 sigma near 1.9 Tc.
            peak = float(np.sqrt(np.max(terms["bias_instability"])))
            out["bias_instability"] = {"sigma": float(np.sqrt(self.g2)), "tau_c": float(tc),
                                       "B": peak / 0.664, "unit": unit,
                                       "read_at": dom("bias_instability")}
        if fit is not None:
            out["allan_fit"] = {
                "white_sigma": float(np.sqrt(fit["s2"])),
                "random_walk_K": float(np.sqrt(fit["q"] / dt)),
                "bias_instability_sigma": float(np.sqrt(fit["g2"])),
                "bias_instability_tau_c": float(-dt / np.log(fit["phi"])) if fit["phi"] > 0 else None,
                "rate_ramp": float(fit["ramp"] / dt), "rate_ramp_unit": f"{unit}/{tu}",
                "method": "weighted least squares on the overlapping Allan variance (allantools), "
                          "weights from its equivalent degrees of freedom"}
        if ad is not None and ad["m"].size:
            out["allan_taus"] = [float(t) for t in ad["tau"]]
        return out


def _mean_min(s):
    """mean over all pairs (i, j) of min(s_i, s_j), without the n x n matrix: in ascending
    order the k-th of n values is the smaller of 2 (n - k) - 1 ordered pairs (k from 1)."""
    a = np.sort(np.asarray(s, float))
    n = a.size
    return float(np.dot(a, 2.0 * (n - np.arange(n)) - 1.0)) / (n * n)


def _mean_pow_gap(s, phi):
    """mean over all pairs (i, j) of phi^|s_i - s_j| (a Gauss-Markov term's correlation), summed
    lag by lag over the sorted times and stopped where phi^gap < 1e-18 for every pair left
    (their sum is then below 1e-18 n^2, within rounding of the diagonal's n): at most half the
    pairs the full matrix would raise to a power, far fewer when Tc is short."""
    a = np.sort(np.asarray(s, float))
    n = a.size
    if n == 0:
        return 0.0
    lphi = float(np.log(phi))
    gmax = np.log(1e-18) / lphi if lphi < 0 else np.inf
    off = 0.0
    for k in range(1, n):
        gap = a[k:] - a[:-k]
        if gap.min() > gmax:        # sorted: every longer lag's gaps are longer still
            break
        off += float(np.sum(np.exp(lphi * gap)))
    return (n + 2.0 * off) / (n * n)


def _last_dom(tau, share):
    k = np.flatnonzero(share > 0.5)
    return float(tau[k[-1]]) if k.size else None


def _poly_acov(c):
    c = np.asarray(c, float)
    return np.array([np.dot(c[:len(c) - k], c[k:]) for k in range(len(c))])


def _whitening(s2, q, g2, phi):
    d = q > 0
    g = g2 > 0
    ar = np.array([1.0])
    if d:
        ar = np.convolve(ar, [1.0, -1.0])
    if g:
        ar = np.convolve(ar, [1.0, -phi])
    order = len(ar) - 1
    if order == 0:
        return np.array([1.0]), np.array([1.0]), s2
    gam = s2 * _poly_acov(ar)
    parts = []
    if d:       # (1 - phi L)^g applied to the walk's increments
        parts.append((q, [1.0, -phi] if g else [1.0]))
    if g:       # (1 - L)^d applied to the Gauss-Markov driving noise
        parts.append((g2 * (1 - phi * phi), [1.0, -1.0] if d else [1.0]))
    for var, c in parts:
        ac = _poly_acov(c)
        gam[:len(ac)] += var * ac
    # Spectral factorisation: gamma(z) = s^2 theta(z) theta(1/z); the roots of the Laurent
    # polynomial come in pairs (r, 1/r); the invertible MA takes those outside the unit circle.
    lp = np.r_[gam[::-1], gam[1:]]
    roots = np.roots(lp)
    out = roots[np.abs(roots) > 1.0]
    if out.size < order:     # a root on the unit circle (numerically): nudge it outside
        out = sorted(roots, key=lambda r: -abs(r))[:order]
        out = np.array([r * (1 + 1e-9) / abs(r) if abs(r) <= 1 else r for r in out])
    ma = np.array([1.0 + 0j])
    for r in out[:order]:
        ma = np.convolve(ma, [1.0, -1.0 / r])
    ma = np.real(ma)
    var = gam[0] / float(np.dot(ma, ma))
    return ar, ma, var


def whiten(x, model, starts, rows=True):
    """Innovations of columns x (n, k) or (n,) under the model, the filter restarted (zero
    state) at each index in starts (starts[0] == 0). rows=False takes x as (k, n), one series
    per row: lfilter runs ~1.4x faster along contiguous memory."""
    b, a, _ = model.filter()
    if len(b) == 1 and len(a) == 1:
        return x
    x = np.asarray(x, float)
    ax = 0 if rows else -1
    if len(starts) == 1:
        out = lfilter(b, a, x, axis=ax)
    else:
        out = np.empty_like(x)
        ends = list(starts[1:]) + [x.shape[ax]]
        for s, e in zip(starts, ends):
            if rows:
                out[s:e] = lfilter(b, a, x[s:e], axis=0)
            else:
                out[..., s:e] = lfilter(b, a, x[..., s:e], axis=-1)
    if out.ndim == 2:
        # A column that is zero after its support (a run's indicator, a local basis function)
        # leaves the filter's decaying tail, which rounding sticks at a few subnormal numbers
        # (x = round(phi x) has fixed points there) for the rest of the segment: every later
        # product with them runs ~50x slower (measured: a 29,412 x 47 Gram matrix 185 ms
        # against 3 ms). Values below 1e-280 add nothing to any sum here. Only a series that
        # ends in zero can end in such a tail; the others (the target, a temperature column)
        # are left alone, which saves a pass over them (a sixth of a noise search's filtering).
        tail = (x[-1] == 0) if rows else (x[..., -1] == 0)
        if tail.all():
            np.putmask(out, np.abs(out) < TINY, 0.0)
        elif tail.any():
            j = np.flatnonzero(tail)
            sub = out[:, j] if rows else out[j]
            np.putmask(sub, np.abs(sub) < TINY, 0.0)
            if rows:
                out[:, j] = sub
            else:
                out[j] = sub
    return out


def level_columns(n, starts, model):
    """One indicator column per filter segment when the bias walks (its level at each restart
    is unknown, a diffuse start); none otherwise."""
    if not model.walks:
        return np.zeros((n, 0))
    L = np.zeros((n, len(starts)))
    ends = list(starts[1:]) + [n]
    for j, (s, e) in enumerate(zip(starts, ends)):
        L[s:e, j] = 1.0
    return L


def restarts(t, dt, seg_starts, model):
    """Where the filter restarts: where the clock restarts, and at a gap long enough for the
    random walk to move by more than the white noise's sigma (q * gap > s2) or for the
    Gauss-Markov term to forget (phi^gap < 1/2). A shorter gap, or a new run whose clock
    runs on, is bridged as if the rows were adjacent."""
    out = [0]
    for s in seg_starts[1:]:
        gap = (t[s] - t[s - 1]) / dt if dt > 0 else 1.0
        if gap <= 0:
            out.append(int(s))
        elif gap > 1.5 and ((model.q * gap > model.s2)
                            or (model.g2 > 0 and model.phi ** gap < 0.5)):
            out.append(int(s))
    return np.array(out, int)


def concentrated_loglik(r, model, starts):
    """Log-likelihood of residual r under the model with the scale concentrated out (the
    whitening filter is monic, so the Jacobian is 1) and a free level per segment when the
    bias walks. Returns (loglik, innovation variance, innovations)."""
    u = whiten(r, model, starts)
    L = level_columns(len(r), starts, model)
    if L.shape[1]:
        Lw = whiten(L, model, starts)
        u = u - Lw @ np.linalg.lstsq(Lw, u, rcond=None)[0]
    n = len(u)
    ss = float(np.dot(u, u))
    s2 = max(ss / n, 1e-300)
    return -0.5 * n * (np.log(2 * np.pi * s2) + 1), s2, u


def estimate(r, dt, starts, s2_init, ad_fit=None):
    """Maximum-likelihood noise model of a fixed residual r (see search). Returns (NoiseModel,
    {kind: loglik})."""
    r = np.asarray(r, float) - np.mean(r)

    def ll_of(q, g2=0.0, phi=0.0):
        ll, s2u, _ = concentrated_loglik(r, NoiseModel(s2_init, q, g2, phi, dt), starts)
        return ll, s2u

    m, lls = search(ll_of, len(r), s2_init, dt, ad_fit)
    return m, {k: v[0] for k, v in lls.items()}


def search(ll_of, n, s2_init, dt, ad_fit=None):
    """Maximum-likelihood noise model given ll_of(q, g2, phi) -> (concentrated log-likelihood,
    innovation variance) with the white variance fixed at s2_init and the scale concentrated
    out (so q and g2 are ratios to it): the random walk's ratio by scipy's bounded Brent
    search; where the Allan fit shows a Gauss-Markov term, its variance ratio and phi too
    (scipy Nelder-Mead from the Allan fit's values). A term joins the model only when it adds
    max(TERM_GAIN, BIC's 0.5 ln n) nats per parameter and matters (see material). Returns
    (NoiseModel, {kind: (loglik, (q, g2, phi) as ratios to s2_init)}) with every kind's
    maximised log-likelihood: the largest of them is the profile likelihood a
    likelihood-ratio test compares."""
    s2 = max(float(s2_init), 1e-300)
    fit = ad_fit or {"q": 0.0, "g2": 0.0, "phi": 0.0}
    phi_lo, phi_hi = np.exp(-1.0 / 1.5), np.exp(-1.0 / max(n / 4.0, 3.0))
    memo = {}

    def ll(q, g2=0.0, phi=0.0):
        k = (q, g2, phi)
        if k not in memo:
            memo[k] = ll_of(q, g2, phi)
        return memo[k][0]

    cands = {"white": (ll(0.0), (0.0, 0.0, 0.0))}
    lq_lo = np.log(1e-4 / n ** 2)          # a walk this small moves < 1 % of sigma over the log
    o = optimize.minimize_scalar(lambda lq: -ll(s2 * np.exp(lq)), bounds=(lq_lo, np.log(1e3)),
                                 method="bounded", options={"xatol": 0.05})
    cands["rw"] = (-o.fun, (s2 * np.exp(o.x), 0.0, 0.0))
    # The Gauss-Markov term is always searched (a model without it would let a walk take
    # what a correlated but bounded bias does): from the Allan fit's values where it shows
    # one, else from the best of a few correlation times.
    def lp(p):
        return (s2 * np.exp(np.clip(p[0], -40, 12)), s2 * np.exp(np.clip(p[1], -20, 12)),
                float(np.clip(1 / (1 + np.exp(-p[2])), phi_lo, phi_hi)))

    starts = []
    if fit.get("g2", 0) > 0.05 * s2 and fit.get("phi", 0) > 0:
        starts.append((np.log(fit["g2"] / s2), float(np.clip(fit["phi"], phi_lo, phi_hi))))
    else:
        for tc in np.geomspace(5.0, max(6.0, n / 8.0), 4):
            starts.append((np.log(0.2), float(np.clip(np.exp(-1.0 / tc), phi_lo, phi_hi))))
    lq0 = o.x if cands["rw"][0] > cands["white"][0] + 0.5 else lq_lo + 2.0
    p0 = max((np.array([lq0, lg, np.log(ph / (1 - ph))]) for lg, ph in starts),
             key=lambda p: ll(*lp(p)))
    o2 = optimize.minimize(lambda p: -ll(*lp(p)), p0, method="Nelder-Mead",
                           options={"xatol": 5e-2, "fatol": 0.1, "maxfev": 60})
    q, g2, phi = lp(o2.x)
    cands["rw+gm"] = (-o2.fun, (q, g2, phi))
    def gm_only(p):
        _, g2_, phi_ = lp(np.r_[0.0, p])
        return -ll(0.0, g2_, phi_)

    o3 = optimize.minimize(gm_only, o2.x[1:], method="Nelder-Mead",
                           options={"xatol": 5e-2, "fatol": 0.1, "maxfev": 40})
    _, g2, phi = lp(np.r_[0.0, o3.x])
    cands["gm"] = (-o3.fun, (0.0, g2, phi))
    nterms = {"white": 0, "rw": 1, "gm": 2, "rw+gm": 3}
    gain = max(TERM_GAIN, 0.5 * np.log(n))     # BIC per parameter, at least TERM_GAIN

    def material(kind):
        # Each term must matter on its own: what it adds over the log (random walk q n / 6,
        # Gauss-Markov g2) at least 2 % of the white variance - else it stays out. A walk
        # that moves nothing still makes the bias's level free at every filter restart
        # (a burst, a run), which frees a temperature law from its levels.
        q, g2, _ = cands[kind][1]
        ok = True
        if "rw" in kind:
            ok &= q * n / 6 > 0.02 * s2
        if "gm" in kind:
            ok &= g2 > 0.02 * s2
        return ok

    best = "white"
    for kind in ("rw", "gm", "rw+gm"):
        if kind in cands and material(kind) and \
                cands[kind][0] > cands[best][0] + gain * (nterms[kind] - nterms[best]):
            best = kind
    q, g2, phi = cands[best][1]
    m = NoiseModel(s2, q, g2, phi, dt)
    ll(q, g2, phi)
    s2u = memo[(q, g2, phi)][1]
    k = s2u / m.filter()[2]      # the scale the likelihood concentrated out
    return NoiseModel(s2 * k, q * k, g2 * k, phi, dt), {kk: (float(v[0]), v[1]) for kk, v in cands.items()}


def gain_z(r0, r1, tau=1.0):
    """z of the drop in sum of squares from r0 to r1 when the noise in r1 has sd(r1) and
    autocorrelation time tau: var(sum(r0^2 - r1^2)) = 4 sd^2 tau sum(delta^2)."""
    delta = r0 - r1
    sd = float(np.std(r1))
    den = 2 * sd * np.sqrt(tau * float(np.sum(delta ** 2)))
    return float(np.sum(r0 ** 2 - r1 ** 2) / den) if den > 0 else 0.0


def describe(model, sigma_white):
    """('white' | 'random walk' | 'bias instability' | 'random walk + bias instability', ratio)
    where ratio is the model's Allan deviation at the longest averaging time over a white
    floor's there - the kind of slow noise no temperature model removes."""
    kind = {(False, False): "white", (True, False): "random walk",
            (False, True): "bias instability",
            (True, True): "random walk + bias instability"}[(model.q > 0, model.g2 > 0)]
    return kind


def classify(x, sigma):
    """What a residual's slow part looks like on its own Allan deviation: ('white', ratio),
    or ('flicker' | 'random walk' | 'correlated', ratio) where ratio = Allan deviation at the
    longest averaging time over what white noise of sigma gives there."""
    ad = allan(x)
    if ad["m"].size < 4 or sigma <= 0:
        return "white", 1.0
    m, a = ad["m"][-1], ad["adev"][-1]
    ratio = a / (sigma / np.sqrt(m))
    if ratio < 2.0:
        return "white", float(ratio)
    half = len(ad["m"]) // 2
    slope = float(np.polyfit(np.log(ad["m"][half:]), np.log(ad["adev"][half:]), 1)[0]) \
        if len(ad["m"]) - half >= 2 else 0.0
    kind = "random walk" if slope > 0.25 else ("flicker" if slope > -0.25 else "correlated")
    return kind, float(ratio)


def block_test(d, tau):
    """One-sided test that mean(d) > 0 with blocks of ceil(tau) samples (their means are
    close to independent). Returns (t, number of blocks, p-value); fewer than MIN_BLOCKS
    blocks give p = 1."""
    n = len(d)
    L = max(1, int(np.ceil(tau)))
    B = n // L
    if B < MIN_BLOCKS:
        return 0.0, B, 1.0
    means = d[:B * L].reshape(B, L).mean(axis=1)
    s = means.std(ddof=1)
    if s == 0:
        return (np.inf, B, 0.0) if means.mean() > 0 else (0.0, B, 1.0)
    t = float(means.mean() / (s / np.sqrt(B)))
    return t, B, float(stats.t.sf(t, B - 1))
