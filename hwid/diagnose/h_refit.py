"""h re-estimated jointly with an effect (:class:`hwid.diagnose.rank.EffectFitter` with
``refit_h``): for a model identified on the plant, h's coefficients (a Legendre basis of w on the
fit data's range) are refitted by linear least squares at every residual of an effect's fit, so
the effect is measured against the best h it allows, not the identification's.

The design matrix is built only on the samples a residual is made of (scored, decimated on the fit
part) where the effect's output stage is pointwise; through a linear stage with memory (a sensor
lag) each column is filtered whole and then sampled.
"""
from __future__ import annotations

import numpy as np

from hwid.blocks.static import legendre_vander
from hwid.diagnose import effects as effect_models


class HRefit:
    """The h-refit half of :class:`hwid.diagnose.rank.EffectFitter` (its attributes: ``_w_c``,
    ``_w_r``, ``degree``, ``_at``, ``_y_at``, ``sf``, ``sfw``, ``svw``, ``refit_g`` and the G maps
    ``_split``, ``_g_sims``)."""

    def _basis(self, w) -> np.ndarray:
        """h's design matrix at ``w``: Legendre polynomials of w mapped to [-1, 1]."""
        return legendre_vander((np.asarray(w, float) - self._w_c) / self._w_r, self.degree)

    def _designs(self, eff, theta, which, scored: bool = False) -> list[np.ndarray]:
        if self.refit_g:
            theta, g = self._split(eff, theta)
            simw = self._g_sims(g)[0 if which == "fit" else 1]
        else:
            simw = self.sfw if which == "fit" else self.svw
        return self._phi(eff, theta, simw, self._at[which] if scored else None)

    def _phi(self, eff, own, simw, at=None) -> list[np.ndarray]:
        """h's design matrix on each experiment of ``simw`` (the model with h = identity) with the
        effect ``eff`` at its own parameters ``own`` (a linear output stage applied to each column);
        at the samples ``at`` of each experiment only, if given."""
        filtered = eff is not None and eff.post_linear and type(eff).post is not effect_models.Effect.post
        out = []
        for i in range(len(simw.inputs)):
            w = simw.w[i] if eff is None else eff.pre(simw, own, i)
            if filtered:        # a linear stage with memory: each column through it whole
                Phi = eff.post(self._basis(w), own, simw.dt)
                out.append(Phi if at is None else Phi[at[i]])
            else:
                out.append(self._basis(w if at is None else w[at[i]]))
        return out

    def _h_coef(self, eff, theta, Phis) -> np.ndarray:
        """h's coefficients (Legendre basis) by least squares on the fit data (``Phis`` on its
        scored samples, :meth:`_designs` with ``scored``); with a non-linear output stage (a clip),
        on the samples the current fit leaves unclipped."""
        A = np.concatenate(Phis)
        b = self._y_at["fit"]
        c = _lsq(A, b)
        if eff is not None and not eff.post_linear:
            # least squares of y - clip(h): an active set, the samples whose prediction the output
            # stage leaves as it is (a clipped sample whose prediction falls short of the limit
            # pulls h up to it; one beyond it costs nothing), iterated to a fixed set. Started
            # from h fitted on the samples the sensor did not clip (strictly inside the limits: a
            # clipping sensor reads its limit), not on all of them (that h bends to the limit and
            # is a fixed point of the iteration too)
            lo, hi = eff.post(np.array([-np.inf, np.inf]), theta, self.sf.dt)
            inside = (b > lo) & (b < hi)
            if inside.sum() > 2 * A.shape[1]:
                c = _lsq(A[inside], b[inside])
            prev = None
            for _ in range(8):
                p = A @ c
                sel = np.abs(eff.post(p, theta, self.sf.dt) - p) <= 0.0
                if sel.sum() <= 2 * A.shape[1] or (prev is not None and np.array_equal(sel, prev)):
                    break
                c = _lsq(A[sel], b[sel])
                prev = sel
        return c

    def _refit_predict(self, eff, theta, which, scored: bool = False) -> list[np.ndarray]:
        """The model with ``eff`` at ``theta`` and h re-estimated on the fit data, on the ``which``
        experiments: whole, or at their scored samples only (``scored``)."""
        if which == "fit" and not scored:
            whole = self._designs(eff, theta, "fit")
            Pf = [P[i] for P, i in zip(whole, self._at["fit"])]
        else:
            Pf = self._designs(eff, theta, "fit", scored=True)
        c = self._h_coef(eff, theta, Pf)
        if which == "fit":
            Ps = Pf if scored else whole
        else:
            Ps = self._designs(eff, theta, "val", scored)
        out = [P @ c for P in Ps]
        if eff is not None and not eff.post_linear:
            out = [eff.post(x, theta, self.sf.dt) for x in out]
        return out


    def noted_predictions(self, eff, theta) -> tuple[list, dict]:
        """A deterministic candidate's validation predictions computed again, with the starts each
        experiment's used (:attr:`hwid.diagnose.modelsim.ModelSim.starts_seen`): ``(predictions,
        {i: starts})``."""
        seen: dict = {}
        sim = self.svw if self.refit_h else self.sv
        sim.starts_seen = seen
        if self.refit_g:
            self._g_cache.clear()       # its simulators are made anew, noting into ``seen``
        try:
            if self.refit_h:
                preds = self._refit_predict(eff, theta, "val")
            else:
                preds = [eff.simulate(self.sv, theta, i) for i in range(len(self.yv))]
        finally:
            sim.starts_seen = None
            if self.refit_g:
                self._g_cache.clear()
        return preds, seen

    def refit_blocks(self, eff, theta):
        """The model a candidate's prediction is, block by block: ``(F, G, h, own)``, F and G as its
        joint fit left them (the model's where they were not re-estimated), h re-estimated on the fit
        data as ascending powers of w (:class:`hwid.blocks.static.PolynomialH`), ``own`` the
        effect's own parameters. Only with ``refit_h``."""
        from hwid.blocks.static import PolynomialH
        if self.refit_g:
            own, g = self._split(eff, theta)
            F, G = self.input_nl(g), self.linear(g)
        else:
            own, F, G = theta, self.svw.model.input, self.svw.model.linear
        c = self._h_coef(eff, theta, self._designs(eff, theta, "fit", scored=True))
        P = np.polynomial
        # sum c_j P_j(s), s = (w - centre) / half-width, in powers of w
        h = P.Polynomial(P.legendre.leg2poly(c))(P.Polynomial([-self._w_c / self._w_r, 1.0 / self._w_r]))
        return F, G, PolynomialH(tuple(float(x) for x in h.coef)), own


def _lsq(A, b) -> np.ndarray:
    """Least squares for a tall, well-conditioned design (h's Legendre basis on [-1, 1]): normal
    equations, or an SVD when they are too ill-conditioned to trust."""
    AtA = A.T @ A
    if np.linalg.cond(AtA) < 1e10:
        return np.linalg.solve(AtA, A.T @ b)
    return np.linalg.lstsq(A, b, rcond=None)[0]
