"""One least-squares fit of the sim plus a set of effect shapes on the training log, and its
residuals on held-out data: the training log's held-out segments (each predicted by a fit on
the other segments) and, when given, the withheld log (predicted by the fit on all of it)."""
import numpy as np

from . import prep
from .effects import BY_NAME
from .features import Context, Prepared
from .model import base_columns

RCOND = 1e-10


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
        self._idx = [np.flatnonzero(self.fold_m == f) for f in range(self.nfold)]
        # A held-out segment scores only where the other segments have been: rows at a
        # temperature (or input) only that segment reaches would judge extrapolation, and a
        # shape that happens to bend the base model's extrapolation would read as an effect.
        Tm, Rm = train.temp[m], train.ref[m]
        keep = np.zeros(int(m.sum()), bool)
        for f, i in enumerate(self._idx):
            o = self.fold_m != f
            if not o.any():
                continue
            lo, hi = Tm[o].min(), Tm[o].max()
            tol = max(0.5, 0.02 * (hi - lo))
            k = (Tm[i] >= lo - tol) & (Tm[i] <= hi + tol)
            for a in range(3):
                rlo, rhi = Rm[o, a].min(), Rm[o, a].max()
                rt = 0.05 * max(rhi - rlo, 1e-12)
                k &= (Rm[i, a] >= rlo - rt) & (Rm[i, a] <= rhi + rt)
            keep[i] = k
        if keep.sum() < 0.3 * keep.size:
            keep[:] = True      # nothing inside: a plateau log; segments judge as they are
        self.cv_keep = keep
        self.cv_fold = self.fold_m[keep]

    def _target(self, p):
        if self.model is None:
            return p.log.out
        return p.log.out - self.model.predict(p.log)

    def _design(self, p, axis, blocks):
        cols = [] if self.model is not None else [base_columns(self.ctx, p.log, axis)]
        for name, shape in blocks:
            e = BY_NAME[name]
            if not e.per_run:
                cols.append(e.columns(self.ctx, p, shape, axis))
        if not cols:
            return np.zeros((len(p), 0))
        return np.column_stack(cols)

    def evaluate(self, axis, blocks, withheld=True):
        """Residuals of sim + blocks for one axis: 'cv' on the training log's masked rows in
        held-out order, 'w' on the withheld log's masked rows (None without one)."""
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        m = self.train.mask
        X = self._design(self.train, axis, blocks)[m]
        y = self.y_t[m, axis]
        if per_run:
            runs = np.unique(self.runs_m)
            X = np.column_stack([X, (self.runs_m[:, None] == runs[None, :]).astype(float)])
        scale = np.sqrt(np.mean(X * X, axis=0)) if X.shape[1] else np.zeros(0)
        scale[scale == 0] = 1.0
        Xs = X / scale
        Gf = [Xs[i].T @ Xs[i] for i in self._idx]
        bf = [Xs[i].T @ y[i] for i in self._idx]
        G, b = sum(Gf), sum(bf)
        r_cv = np.empty_like(y)
        for f, i in enumerate(self._idx):
            beta = _solve(G - Gf[f], b - bf[f])
            r_cv[i] = y[i] - Xs[i] @ beta
            if per_run:
                # A run wholly inside the held-out block has no fitted constant: capture it
                # from the block's first samples of that run, as for a withheld log.
                seen = np.isin(self.runs_m[i], self.runs_m[self.fold_m != f])
                r_cv[i] = _startup_correct(r_cv[i], self.runs_m[i], ~seen)
        out = {"cv": r_cv[self.cv_keep], "w": None}
        if withheld and self.withheld is not None:
            pw = self.withheld
            beta = _solve(G, b)
            Xw = self._design(pw, axis, blocks)[pw.mask]
            if per_run:
                Xw = np.column_stack([Xw, np.zeros((Xw.shape[0], len(np.unique(self.runs_m))))])
            rw = self.y_w[pw.mask, axis] - (Xw / scale) @ beta if Xw.shape[1] else self.y_w[pw.mask, axis].copy()
            if per_run:
                wr = pw.log.run[pw.mask] if pw.log.run is not None else np.zeros(len(rw), int)
                rw = _startup_correct(rw, wr, np.ones(len(rw), bool))
            out["w"] = rw
        return out

    def full_residual(self, p, axis, blocks):
        """Residual on every row of prepared log p (training fit on all masked rows) - for
        the localisation and the plots, not for scoring."""
        m = self.train.mask
        X = self._design(self.train, axis, blocks)[m]
        y = self.y_t[m, axis]
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        runs = np.unique(self.runs_m)
        if per_run:
            X = np.column_stack([X, (self.runs_m[:, None] == runs[None, :]).astype(float)])
        scale = np.sqrt(np.mean(X * X, axis=0)) if X.shape[1] else np.zeros(0)
        scale[scale == 0] = 1.0
        beta = _solve((X / scale).T @ (X / scale), (X / scale).T @ y) if X.shape[1] else np.zeros(0)
        Xp = self._design(p, axis, blocks)
        if per_run:
            if p is self.train:
                Xp = np.column_stack([Xp, (self.runs_t[:, None] == runs[None, :]).astype(float)])
            else:
                Xp = np.column_stack([Xp, np.zeros((len(p), len(runs)))])
        yp = self._target(p)[:, axis]
        r = yp - (Xp / scale) @ beta if Xp.shape[1] else yp.copy()
        if per_run and p is not self.train:
            rr = p.log.run if p.log.run is not None else np.zeros(len(p), int)
            r = _startup_correct(r, rr, np.ones(len(r), bool))
        return r


    def coefficients(self, axis, blocks):
        """The fit on every masked training row in physical units: (base or None when the sim
        is given, [(effect, shape, coefficients)], per-run constants {run: c} or None)."""
        m = self.train.mask
        X = self._design(self.train, axis, blocks)[m]
        y = self.y_t[m, axis]
        per_run = any(BY_NAME[n].per_run for n, _ in blocks)
        runs = np.unique(self.runs_m)
        if per_run:
            X = np.column_stack([X, (self.runs_m[:, None] == runs[None, :]).astype(float)])
        scale = np.sqrt(np.mean(X * X, axis=0)) if X.shape[1] else np.zeros(0)
        scale[scale == 0] = 1.0
        Xs = X / scale
        beta = _solve(Xs.T @ Xs, Xs.T @ y) / scale if X.shape[1] else np.zeros(0)
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


def _solve(G, b):
    if G.shape[0] == 0:
        return np.zeros(0)
    return np.linalg.lstsq(G, b, rcond=RCOND)[0]


def _startup_correct(r, runs, unseen):
    """Give each run the fit never saw its own constant (the mean of its residual): that is
    what 'the offset differs from run to run' predicts - one unknown number per power-on,
    which a user captures at start-up. One number per run costs the score next to nothing."""
    r = r.copy()
    for run in np.unique(runs[unseen]):
        idx = (runs == run) & unseen
        r[idx] -= np.mean(r[idx])
    return r
