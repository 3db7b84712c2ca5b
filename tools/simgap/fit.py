"""One generalised least-squares fit of the sim plus a set of effect shapes on the training log
under the axis's noise model, and its residuals on held-out data: the training log's held-out
segments (one-step-ahead innovations, each segment predicted by a fit on the others) and, when
given, the withheld log (predicted by the fit on all of it).

Under white noise the fit is ordinary least squares. Under a wandering bias (random walk,
Gauss-Markov) every column is passed through the noise model's whitening filter (the
steady-state Kalman innovations, noise.whiten) and the fit is least squares on the filtered
columns, which is exact GLS, O(n k). The filter runs through the held-out segment (the
innovations there are one-step-ahead predictions from everything before), and the rows just
after it, whose filtered values still carry its data, are left out of that segment's fit."""
import numpy as np

from . import noise as N
from . import prep
from .effects import BY_NAME
from .features import Context, Prepared
from .model import base_columns

RCOND = 1e-10
RCOND_WALK = 1e-9   # under a non-white noise model: a ridge of 1e-9 x the mean information
                    # per column keeps a direction the filtered rows never see at 0 (a stronger
                    # ridge, 1e-5, blurred the thermal lag's nearly collinear columns)


class Problem:
    """Everything fixed for one diagnosis: the logs, their masks, folds and targets."""

    def __init__(self, train, withheld=None, model=None):
        self.ctx = Context(train)
        self.model = model
        self.train = Prepared(train, self.ctx, ~prep.spikes(train))
        self.withheld = None
        if withheld is not None:
            self.withheld = Prepared(withheld, self.ctx, ~prep.spikes(withheld))
        self.fold = prep.folds(train)
        self.nfold = int(self.fold.max()) + 1
        self.y_t = self._target(self.train)
        self.y_w = self._target(self.withheld) if self.withheld is not None else None
        m = self.train.mask
        self.runs_t = train.run if train.run is not None else np.zeros(len(train), int)
        self.fold_m = self.fold[m]
        self.runs_m = self.runs_t[m]
        self._run_starts_m = np.flatnonzero(np.r_[False, np.diff(self.runs_m) != 0])
        self._idx = [np.flatnonzero(self.fold_m == f) for f in range(self.nfold)]
        # The segments are contiguous (prep.folds): as slices their Gram matrices read the
        # filtered design in place instead of copying each segment's rows.
        self._sl = [slice(int(i[0]), int(i[-1]) + 1) if i.size and i[-1] - i[0] + 1 == i.size
                    else i for i in self._idx]
        # A held-out segment scores only where the other segments have been: rows at a
        # temperature (or input) only that segment reaches would judge extrapolation, and a
        # shape that happens to bend the base model's extrapolation would read as an effect.
        self._Tm, self._Rm = train.temp[m], train.ref[m]
        keep = np.zeros(int(m.sum()), bool)
        for f, i in enumerate(self._idx):
            o = self.fold_m != f
            if o.any():
                keep[i] = self._covered(i, o)
        self._cover_all = keep.sum() < 0.3 * keep.size
        if self._cover_all:
            keep[:] = True      # nothing inside: a plateau log; segments judge as they are
        self.cv_keep = keep
        self._scored_cache = {}
        self.cv_fold = self.fold_m[keep]
        # Noise model per axis (white until the selection estimates one) and the filtered
        # designs it implies, cached for the current state's blocks.
        self.noise = {a: N.NoiseModel(1.0, dt=self.ctx.dt) for a in range(3)}
        self._seg_t = self._segment_starts(self.train)
        self._seg_w = self._segment_starts(self.withheld) if self.withheld is not None else None
        self._wcache = {}
        self._rcache = {}
        self._rcache_y = {}
        self._ccache = {}
        self._zraw = (None, None)

    def _segment_starts(self, p):
        """Start rows (in masked-row order) of the log's contiguous stretches."""
        m = p.mask
        seg = prep.segments(p.log)
        pos = np.cumsum(m) - 1              # masked index of each row
        out = []
        for s in seg:
            k = s
            while k < len(m) and not m[k]:
                k += 1
            if k < len(m):
                out.append(int(pos[k]))
        return np.unique(np.array(out or [0], int))

    def set_noise(self, axis, model):
        self.noise[axis] = model
        self._wcache = {k: v for k, v in self._wcache.items() if k[0] != axis}

    def starts(self, p, axis, model=None):
        """Filter restarts (masked-row indices) on prepared log p under the axis's noise model."""
        model = model or self.noise[axis]
        seg = self._seg_t if p is self.train else self._seg_w
        if "t_masked" not in p.cache:
            p.cache["t_masked"] = p.log.t[p.mask]
        t = p.cache["t_masked"]
        return N.restarts(t, self.ctx.dt, seg, model)

    def _target(self, p):
        if self.model is None:
            return p.log.out
        return p.log.out - self.model.predict(p.log)

    def _design(self, p, axis, blocks):
        cols = [] if self.model is not None else [self._base_columns(p, axis)]
        for name, shape in blocks:
            e = BY_NAME[name]
            if not e.per_run:
                cols.append(e.columns(self.ctx, p, shape, axis))
        if not cols:
            return np.zeros((len(p), 0))
        return np.column_stack(cols)

    def _base_columns(self, p, axis):
        """The sim's regressors on prepared log p, built once per log and axis (every design
        starts with them; column_stack copies, so the cached array is never written)."""
        key = ("base_columns", axis)
        if key not in p.cache:
            p.cache[key] = base_columns(self.ctx, p.log, axis)
        return p.cache[key]

    def _train_design(self, axis, blocks, model):
        """(X raw on masked training rows with per-run and level columns, scale, Xs filtered
        and scaled, number of level columns). Level columns (one per filter restart after
        the first) give a walking bias a free level where the filter restarts; the base
        intercept is the first segment's."""
        m = self.train.mask
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        key = (axis, model.key(), tuple((n, _shape_key(s)) for n, s in blocks))
        if key in self._wcache:
            return self._wcache[key]
        st = self.starts(self.train, axis, model)
        pkey = (axis, model.key(), key[2][:-1], "prefix")
        last = blocks[-1] if blocks else None
        plain = not model.is_white and not per_run and len(st) == 1
        if blocks and plain and pkey in self._wcache:
            # The state's filtered columns are cached; only the candidate's are filtered.
            X0, Xw0 = self._wcache[pkey]
            Xn = BY_NAME[last[0]].columns(self.ctx, self.train, last[1], axis)[m]
            X = np.column_stack([X0, Xn])
            Xw = np.column_stack([Xw0, N.whiten(Xn, model, st)])
            nlev = 0
        else:
            X = self._raw_design(axis, blocks, key[2], per_run)
            nlev = 0
            if model.walks and len(st) > 1:
                L = N.level_columns(len(X), st, model)[:, 1:]
                X = np.column_stack([X, L])
                nlev = L.shape[1]
            Xw = N.whiten(X, model, st) if X.shape[1] else X
        # Each column scaled by its RMS after the filter: under a walking bias a slow column
        # (a spline in temperature) keeps only its small differences, and the solve's rank
        # cut must judge it at that size, not against its raw size.
        scale = np.sqrt(np.mean(Xw * Xw, axis=0)) if X.shape[1] else np.zeros(0)
        scale[scale == 0] = 1.0
        Xs = Xw / scale
        while len(self._wcache) > 4:
            self._wcache.pop(next(iter(self._wcache)))
        out = (X, scale, Xs, nlev, st)
        if X.shape[1] <= 40:
            self._wcache[key] = out
            if plain:
                self._wcache[(axis, model.key(), key[2], "prefix")] = (X, Xw)
        return out

    def _raw_design(self, axis, blocks, bkey, per_run):
        """The unfiltered design on the masked training rows (with the per-run columns), which
        does not depend on the noise model: the noise searches evaluate one design under
        hundreds of noise models, and building it each time was a third of a long log's
        diagnosis. Read-only, so a caller cannot change the cached copy."""
        rkey = (axis, bkey)
        X = self._rcache.pop(rkey, None)
        if X is None:
            m = self.train.mask
            cols = [] if self.model is not None else \
                [self._masked(("base", axis), lambda: self._base_columns(self.train, axis)[m])]
            for (name, shape), (_, sk) in zip(blocks, bkey):
                e = BY_NAME[name]
                if not e.per_run:
                    cols.append(self._masked((name, sk, axis), lambda e=e, shape=shape:
                                             e.columns(self.ctx, self.train, shape, axis)[m]))
            X = np.column_stack(cols) if cols else np.zeros((int(m.sum()), 0))
            if per_run:
                runs = np.unique(self.runs_m)
                X = np.column_stack([X, (self.runs_m[:, None] == runs[None, :]).astype(float)])
            X.flags.writeable = False
            while len(self._rcache) >= 12:      # at most 12 designs (30,000 rows: ~100 MB)
                self._rcache.pop(next(iter(self._rcache)))
        self._rcache[rkey] = X                  # most recently used last
        return X

    def _masked(self, key, build):
        """One effect's (or the sim's) columns on the masked training rows, kept for the
        designs that share them (the state's effects recur in every candidate's design and
        every continuous parameter a search tries); at most 64 blocks (30,000 rows: ~60 MB)."""
        c = self._ccache.pop(key, None)
        if c is None:
            c = build()
            c.flags.writeable = False
            while len(self._ccache) >= 64:
                self._ccache.pop(next(iter(self._ccache)))
        self._ccache[key] = c
        return c

    def prime(self, axis, blocks):
        """Filter the state's design once, so each candidate filters only its own columns."""
        self._train_design(axis, blocks, self.noise[axis])

    def _yw(self, axis, model, st):
        key = (axis, model.key(), "y")
        if key not in self._wcache:
            self._wcache[key] = N.whiten(self._ymasked(axis), model, st)
        return self._wcache[key]

    def _covered(self, i, o):
        """Rows i inside the temperature and input range of the rows o (with a small margin)."""
        Tm, Rm = self._Tm, self._Rm
        lo, hi = Tm[o].min(), Tm[o].max()
        tol = max(0.5, 0.02 * (hi - lo))
        k = (Tm[i] >= lo - tol) & (Tm[i] <= hi + tol)
        for a in range(3):
            rlo, rhi = Rm[o, a].min(), Rm[o, a].max()
            rt = 0.05 * max(rhi - rlo, 1e-12)
            k &= (Rm[i, a] >= rlo - rt) & (Rm[i, a] <= rhi + rt)
        return k

    def _scored(self, f, i, j):
        """Rows of held-out segment f (indices i) that it scores when the fit also leaves out the
        rows j after it (a non-white filter's memory, evaluate): cv_keep, and inside the range of
        the rows the fit still has. cv_keep is the range of every other segment; without this,
        a segment whose neighbour's first half held the only other visit to a temperature was
        scored there on a pure extrapolation (measured on the full blind set's offset_temperature +
        drift pair at seed 2: a spline's held-out innovations of -100 LSB at the end of the first
        segment, its neighbour's first half the only other visit above 45 degC, so the law lost
        by 1e8 LSB^2 there while it gained in every segment it was judged on)."""
        key = (f, int(j.size))
        if key not in self._scored_cache:
            k = self.cv_keep[i].copy()
            if j.size and not self._cover_all:
                o = self.fold_m != f
                o[j] = False
                k &= self._covered(i, o) if o.any() else False
            self._scored_cache[key] = k
        return self._scored_cache[key]

    def evaluate(self, axis, blocks, withheld=True, model=None):
        """Residuals of sim + blocks for one axis under the axis's noise model (or `model`):
        'cv' the one-step-ahead innovations of the training log's held-out segments (masked
        rows in held-out order; plain residuals under white noise), 'w' the withheld log's
        residuals (None without one), 's2' the innovation variance the noise model implies."""
        model = model or self.noise[axis]
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        X, scale, Xs, nlev, st0 = self._train_design(axis, blocks, model)
        y = self._yw(axis, model, st0)
        yr = self._ymasked(axis)
        Gf = [Xs[i].T @ Xs[i] for i in self._sl]
        bf = [Xs[i].T @ y[i] for i in self._sl]
        G, b = sum(Gf), sum(bf)
        r_cv = np.empty_like(y)
        B = 0 if model.is_white else model.memory()
        for f, i in enumerate(self._idx):
            Gk, bk = G - Gf[f], b - bf[f]
            j = np.zeros(0, int)
            if B and i.size:
                # Rows just after the held-out segment carry its data through the filter.
                j = np.arange(i[-1] + 1, min(len(y), i[-1] + 1 + min(B, max(1, i.size // 2))))
                j = j[self.fold_m[j] != f]
                if j.size:
                    Gk = Gk - Xs[j].T @ Xs[j]
                    bk = bk - Xs[j].T @ y[j]
            beta = _solve(Gk, bk, RCOND if model.is_white else RCOND_WALK)
            if not model.is_white:
                # One-step-ahead from everything before the held-out segment: the filter
                # carries the bias's state in. Where a walking bias's filter segment starts
                # inside it, or a power-on does (its constant captured at start-up, as for a
                # withheld log), the level is unknown (diffuse): the first observation sets it
                # and its innovation carries no information (0). Rows it does not score
                # (beyond what the other segments cover) do not feed the filter: it restarts
                # at the first scored row after them.
                # Only the rows that reach the segment through the filter's memory matter.
                w0 = int(i[0])
                lo = max(0, w0 - B)
                prev = st0[st0 <= w0]
                if prev.size:
                    lo = max(lo, int(prev[-1]))
                hi = int(i[-1]) + 1
                z = np.zeros(len(yr))
                z[lo:hi] = yr[lo:hi] - (X[lo:hi] / scale) @ beta
                rst = np.union1d(st0, [lo])
                diffuse = st0[self.fold_m[st0] == f] if model.walks else np.zeros(0, int)
                if per_run:
                    rs = self._run_starts_m[self.fold_m[self._run_starts_m] == f]
                    diffuse = np.union1d(diffuse, rs)
                sc = self._scored(f, i, j)
                out_i = i[~sc]
                if out_i.size:
                    z[out_i] = 0.0
                    after = out_i + 1
                    after = after[after < len(z)]
                    after = after[np.isin(after, i[sc])]
                    rst = np.union1d(rst, after)
                    if model.walks:
                        diffuse = np.union1d(diffuse, after)
                rst = np.union1d(rst, diffuse).astype(int)
                for s0 in diffuse:
                    nxt = rst[rst > s0]
                    z[s0:(nxt[0] if nxt.size else len(z))] -= z[s0]
                rw = rst[(rst >= lo) & (rst < hi)] - lo
                u = N.whiten(z[lo:hi], model, rw)
                u[diffuse.astype(int) - lo] = 0.0
                r_cv[i] = u[i - lo]
                r_cv[out_i] = 0.0   # kept by cv_keep but not scored here: no evidence either way
            else:
                r_cv[i] = y[i] - Xs[i] @ beta
            if per_run:
                # A run wholly inside the held-out block has no fitted constant: capture it
                # from the block's first samples of that run, as for a withheld log.
                seen = np.isin(self.runs_m[i], self.runs_m[self.fold_m != f])
                r_cv[i] = _startup_correct(r_cv[i], self.runs_m[i], ~seen)
        beta = _solve(G, b, RCOND if model.is_white else RCOND_WALK)
        out = {"cv": r_cv[self.cv_keep], "w": None, "s2": model.filter()[2],
               "ins": y - Xs @ beta if X.shape[1] else y}
        if withheld and self.withheld is not None:
            pw = self.withheld
            k = X.shape[1] - nlev
            Xw = self._design(pw, axis, blocks)[pw.mask]
            if per_run:
                Xw = np.column_stack([Xw, np.zeros((Xw.shape[0], len(np.unique(self.runs_m))))])
            rw = self.y_w[pw.mask, axis] - (Xw / scale[:k]) @ beta[:k] if Xw.shape[1] \
                else self.y_w[pw.mask, axis].copy()
            if per_run:
                wr = pw.log.run[pw.mask] if pw.log.run is not None else np.zeros(len(rw), int)
                rw = _startup_correct(rw, wr, np.ones(len(rw), bool))
            out["w"] = rw
        return out

    def loglik(self, axis, blocks, model):
        """(log-likelihood, innovation variance) of sim + blocks on the masked training rows
        under the noise model, the effects' coefficients (and a walking bias's levels) at
        their GLS estimates and the scale concentrated out: maximised over the noise model's
        parameters, this is the profile likelihood of the state-space model."""
        u = self._loglik_uncached(axis, blocks, model)
        if u is None:
            X, scale, Xs, nlev, st = self._train_design(axis, blocks, model)
            y = self._yw(axis, model, st)
            if X.shape[1]:
                beta = _solve(Xs.T @ Xs, Xs.T @ y, RCOND if model.is_white else RCOND_WALK)
                u = y - Xs @ beta
            else:
                u = y
        n = len(u)
        s2 = max(float(np.dot(u, u)) / n, 1e-300)
        return -0.5 * n * (np.log(2 * np.pi * s2) + 1), s2

    def _loglik_uncached(self, axis, blocks, model):
        """The GLS innovations of loglik() for a noise model met once (a noise search tries
        about a hundred, each once), or None where the cached path applies (a white model, or
        the design already filtered under this model). One filter pass over the design and
        the target together, the column scaling and the normal equations from one Gram
        matrix: the same solve as _train_design + loglik without keeping the filtered copy,
        its scaled copy, or evicting the state's cached designs."""
        if model.is_white:
            return None
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        bkey = tuple((n, _shape_key(s)) for n, s in blocks)
        key = (axis, model.key(), bkey)
        plain = not per_run
        if key in self._wcache or (blocks and plain and (axis, model.key(), bkey[:-1], "prefix")
                                   in self._wcache):
            return None
        st = self.starts(self.train, axis, model)
        zkey = (axis, bkey, tuple(st) if model.walks else ())
        if self._zraw[0] != zkey:      # a noise search: one design under ~100 noise models
            X = self._raw_design(axis, blocks, bkey, per_run)
            cols = [X]
            if model.walks and len(st) > 1:
                cols.append(N.level_columns(len(X), st, model)[:, 1:])
            cols.append(self._ymasked(axis)[:, None])
            # one row per column: the filter runs along contiguous memory (noise.whiten)
            self._zraw = (zkey, np.ascontiguousarray(np.column_stack(cols).T))
        Z = N.whiten(self._zraw[1], model, st, rows=False)
        k = Z.shape[0] - 1
        y = Z[k]
        if k == 0:
            return y
        G = Z @ Z.T
        n = len(y)
        scale = np.sqrt(np.diag(G)[:k] / n)
        scale[scale == 0] = 1.0
        beta = _solve(G[:k, :k] / np.outer(scale, scale), G[:k, k] / scale, RCOND_WALK)
        return y - (beta / scale) @ Z[:k]

    def _ymasked(self, axis):
        key = ("ymasked", axis)
        if key not in self._rcache_y:
            self._rcache_y[key] = self.y_t[self.train.mask, axis]
        return self._rcache_y[key]

    def _beta(self, axis, blocks, model=None):
        model = model or self.noise[axis]
        X, scale, Xs, nlev, st = self._train_design(axis, blocks, model)
        y = self._yw(axis, model, st)
        beta = _solve(Xs.T @ Xs, Xs.T @ y, RCOND if model.is_white else RCOND_WALK) \
            if X.shape[1] else np.zeros(0)
        return beta, scale, nlev, X

    def full_residual(self, p, axis, blocks, model=None):
        """Residual on every row of prepared log p (the fit on all masked training rows under
        the axis's noise model) - for the localisation, the noise model and the plots."""
        beta, scale, nlev, X = self._beta(axis, blocks, model)
        k = len(beta) - nlev
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        runs = np.unique(self.runs_m)
        Xp = self._design(p, axis, blocks)
        if per_run:
            if p is self.train:
                Xp = np.column_stack([Xp, (self.runs_t[:, None] == runs[None, :]).astype(float)])
            else:
                Xp = np.column_stack([Xp, np.zeros((len(p), len(runs)))])
        yp = self._target(p)[:, axis]
        r = yp - (Xp / scale[:k]) @ beta[:k] if Xp.shape[1] else yp.copy()
        if nlev and p is self.train:
            lev = np.zeros(len(p))
            lev[self.train.mask] = (X[:, k:] / scale[k:]) @ beta[k:]
            r = r - lev
        if per_run and p is not self.train:
            rr = p.log.run if p.log.run is not None else np.zeros(len(p), int)
            r = _startup_correct(r, rr, np.ones(len(r), bool))
        return r

    def coefficients(self, axis, blocks):
        """The fit on every masked training row in physical units: (base or None when the sim
        is given, [(effect, shape, coefficients)], per-run constants {run: c} or None)."""
        beta, scale, nlev, X = self._beta(axis, blocks)
        beta = beta[:len(beta) - nlev] / scale[:len(beta) - nlev]
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        runs = np.unique(self.runs_m)
        k = 0
        base = None
        if self.model is None:
            keep = self.ctx.base[axis][0]
            nb = int(sum(keep))
            base = np.zeros(5)
            base[np.flatnonzero(keep)] = beta[:nb]   # unidentified parameters stay 0
            k = nb
        parts = []
        for name, shape in blocks:
            if BY_NAME[name].per_run:
                continue
            w = BY_NAME[name].columns(self.ctx, self.train, shape, axis).shape[1]
            parts.append((name, shape, beta[k:k + w]))
            k += w
        tob = {int(r): float(c) for r, c in zip(runs, beta[k:])} if per_run else None
        return base, parts, tob


def _shape_key(s):
    if isinstance(s, tuple):
        return tuple(_shape_key(x) for x in s)
    if isinstance(s, (float, np.floating)):
        return float(s)
    return s


def _solve(G, b, rcond=RCOND):
    if G.shape[0] == 0:
        return np.zeros(0)
    if rcond > RCOND:
        # Walking bias: a ridge of rcond x the mean information per column, so a direction
        # the filtered training rows barely see is shrunk to 0 instead of fitted huge.
        G = G + rcond * np.trace(G) / G.shape[0] * np.eye(G.shape[0])
    return np.linalg.lstsq(G, b, rcond=RCOND)[0]


def demean_runs(r, runs):
    """A copy of r less each run's own mean (every row unseen by the fit: _startup_correct)."""
    return _startup_correct(r, runs, np.ones(len(r), bool))


def _startup_correct(r, runs, unseen):
    """Give each run the fit never saw its own constant (the mean of its residual): that is
    what 'the offset differs from run to run' predicts - one unknown number per power-on,
    which a user captures at start-up. One number per run costs the score next to nothing."""
    r = r.copy()
    for run in np.unique(runs[unseen]):
        idx = (runs == run) & unseen
        r[idx] -= np.mean(r[idx])
    return r
