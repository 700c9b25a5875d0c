"""Stage 1: the output nonlinearity h and the backlash borders from two staircases (paper Section 4).

The data
--------
The ascending staircase (eq. 6) and the descending one (eq. 13) are run after their lead-ins
(:mod:`hwid.protocols`). For each level the steady output ``X_hat_j`` is the mean of ``y`` after the
transient (eq. 9), with a standard error that holds under coloured noise (:mod:`hwid.identify.steady`).

The model
---------
Everything is estimated for the normalised model of eqs. (4a-c) (``slope_up = 1``, ``G(0) = 1``),
in which the steady output at a level is ``X_j = h_bar(F_bar[U_j])`` (eqs. 5, 8). For a Backlash
``F_bar`` has the borders ``u - d^+`` and ``S^d/S^a (u - d^-)``. For a Backlash-Inverse the same
normalisation (``F_bar = S^a F``) gives the branches ``u + S^a d^+`` (ascending) and
``(S^a/S^d) u + S^a d^-`` (descending); hwid reports it as ``slope_down = S^d/S^a``,
``d_plus = S^a d^+``, ``d_minus = S^a d^-`` (see :mod:`hwid.model`), so its branches read
``u + d_plus`` and ``u / slope_down + d_minus``.

In both cases the two branches are straight lines ``asc(u) = u - a`` and
``desc(u) = sigma (u - b)``, with ``(a, sigma, b) = (d^+, S^d, d^-)`` for a Backlash and
``(-d^+, 1/S^d, -S^d d^-)`` for a Backlash-Inverse; the paper's closed-form route works on
``(a, sigma, b)`` and maps back.

The estimator (:class:`NonlinearEstimator`)
-------------------------------------------
1. Steady states and standard errors of all levels.
2. ``j_a``, ``j_d`` (eqs. 7a, 14a) by sequential tests: a level belongs to the horizontal path while
   it equals the path's weighted mean within a Bonferroni-corrected two-sided z test (family level
   ``alpha`` per staircase). The descending path is referred to the last ascending level, whose
   steady state ``h(U_N - d^+)`` is the one the descending lead-in leaves. A staircase that never
   leaves the path means ``[u_m, u_M]`` is too narrow (Section 3, Fig. 6a): :class:`HwidError`.
3. The paper's route (eqs. 11-14): a weighted polynomial fit ``q(u) = h_bar(u - d^+)`` on the
   ascending border points in numpy's domain-scaled basis; ``d^+`` from a real root of ``q``
   (Remark 1.3: ``h^-1(0) = 0``), the root being the one whose whole model fits both staircases
   best; ``h_bar(w) = q(w + d^+)`` (eq. 12); on the descending border a fit ``r(u) = h_bar(S^d(u - d^-))``
   gives ``S^d = (r_p / c_p)^(1/p)`` from the leading coefficients and ``d^-`` from ``r``'s root
   (eq. 14).
4. ``method='nls'`` (default): all parameters ``(c_1..c_p, d^+, S^d, d^-)`` refined jointly by
   weighted least squares on both staircases, the model being ``h_bar`` of the steady-state
   recursion of ``F_bar`` over all levels including the lead-in, so which levels lie on the flat
   path or on a border follows the parameters. Started from step 3.
5. Degree ``p`` and type (Backlash / Backlash-Inverse, Remark 1.4) by BIC of the joint fit
   ``chi^2 + k ln n``, ``p`` limited by eq. (11) (``N - j_a >= p + 1``) unless the joint fit
   at that limit still misfits: then higher degrees are fitted jointly (both staircases sample
   ``h``) while the misfit lasts and each added coefficient passes an F test; each degree's fit
   also starts from the one below with ``c_p = 0``. A configured degree overrides the selection.
   Fits whose ``h_bar`` has another real zero where the data go are set aside while one that keeps
   Remark 1.3 exists. When no candidate fits within noise (the plant is
   not quite of this structure: a drift, curved borders), the type is chosen by the
   quasi-likelihood BIC ``chi^2 / c + k ln n`` with ``c`` the best fit's ``chi^2/dof``; the
   degree within the type still by the BIC.
6. 95 % intervals from the covariance ``(J^T W J)^-1`` (nls) or from the delta method through the
   closed form (paper), with t quantiles on the noise's degrees of freedom.

What the staircases can determine is counted before the fit, as for a recorded history
(:mod:`hwid.identify.determinable`): fewer than 2 distinct levels on a branch is one line naming the
parameters and the levels that would determine them. After it, an estimate whose interval cannot
stand as one (not finite, of zero width, a border's wider than the levels' whole range, a slope's
reaching zero) is reported undetermined (:func:`undetermined`): interval None and the reason; so
are the borders and h_bar where h_bar's root-shifted readings leave them open (:func:`_anchored`).
``slope_up`` and h_bar's constant are fixed by the normalisation: no interval.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Optional

import numpy as np
from scipy import special

from hwid import HwidError
from hwid.identify import determinable, readings
from hwid.identify.closed_form import Route, TooFewLevels, flat_run, paper_route, route_with_paths, weighted_polyfit
from hwid.identify.joint_fit import grid_starts, grid_V, nls_cov, nls_fit, one_degree_up, overdispersion
from hwid.identify.result import Level, NonlinearResult
from hwid.identify.stage1_model import (LevelData, ascending_index, internal_levels, joint_chi2, other_zeros,
                                        path_memberships, pick_fit)
from hwid.identify.steady import SteadyLevels, steady_levels
from hwid.results import read_experiments

TYPES = ("backlash", "backlash_inverse")

#: a level that reads a sensor rail gets this many times the largest |X_hat| as its standard error:
#: no fit of h follows it (:meth:`NonlinearEstimator._off_the_rails`)
RAIL_SE = 1e4


class NonlinearIdentificationError(HwidError):
    """Stage 1 cannot proceed with these data (narrow working interval, too few levels, ...)."""


# ----------------------------------------------------------------------------------------- result

# ----------------------------------------------------------------------------------- the model

@dataclass
class _Candidate:
    kind: str
    p: int
    theta: np.ndarray
    chi2: float
    bic: float
    route: Optional[Route] = None
    ambiguous: bool = False      # other roots of q fit as well (h has another zero in range)
    j_a: int = 0                 # horizontal paths the closed form used
    j_d: int = 0
    qbic: float = float("nan")   # the type's criterion: BIC, or quasi-likelihood BIC under a misfit
    other_zeros: int = -1        # real zeros of h_bar other than 0 where the data go (-1: not computed)


class NonlinearEstimator:
    """Stage-1 estimator (Section 4) in the scikit-learn manner.

    Parameters
    ----------
    method : {"nls", "paper"}
        ``"nls"``: joint weighted nonlinear least squares started from the closed form;
        ``"paper"``: the closed-form route of eqs. (11-14) only.
    degree : int, optional
        Degree ``p`` of ``h``; selected by BIC when None.
    max_degree : int
        Highest degree tried by the selection.
    input_type : {"auto", "backlash", "backlash_inverse"}
        Type of F; decided from the data when "auto" (Remark 1.4).
    alpha : float
        Family-wise level of the flat-path tests per staircase (j_a, j_d).
    pool_noise : bool
        Pool the long-run noise variance over levels (stationary noise).
    confidence : float
        Level of the reported intervals.

    Attributes (after ``fit``)
    --------------------------
    result_ : NonlinearResult
    steady_ : hwid.identify.steady.SteadyLevels
    type_, degree_, d_plus_, slope_down_, d_minus_, h_coef_, flat_up_, flat_down_, selection_
    """

    def __init__(self, method: str = "nls", degree: Optional[int] = None, max_degree: int = 9,
                 input_type: str = "auto", alpha: float = 0.01, pool_noise: bool = True,
                 confidence: float = 0.95):
        self.method = method
        self.degree = degree
        self.max_degree = max_degree
        self.input_type = input_type
        self.alpha = alpha
        self.pool_noise = pool_noise
        self.confidence = confidence

    @classmethod
    def from_config(cls, cfg) -> "NonlinearEstimator":
        """Settings from ``cfg.identification.nonlinear``."""
        settings = cfg.identification.nonlinear
        return cls(method=settings.method, degree=settings.degree, max_degree=settings.max_degree,
                   input_type=settings.input_type, alpha=settings.alpha, pool_noise=settings.pool_noise)

    # -------------------------------------------------------------------------------- fit
    def _check_settings(self):
        if self.method not in ("nls", "paper"):
            raise ValueError(f"method must be 'nls' or 'paper', got {self.method!r}")
        if self.input_type not in ("auto",) + TYPES:
            raise ValueError(f"input_type must be 'auto', 'backlash' or 'backlash_inverse', got {self.input_type!r}")
        if self.degree is not None and not (isinstance(self.degree, (int, np.integer)) and self.degree >= 1):
            raise ValueError(f"degree must be a positive integer or None, got {self.degree!r}")
        if not (isinstance(self.max_degree, (int, np.integer)) and self.max_degree >= 1):
            raise ValueError(f"max_degree must be a positive integer, got {self.max_degree!r}")
        if not 0 < self.alpha < 1 or not 0 < self.confidence < 1:
            raise ValueError("alpha and confidence must lie in (0, 1)")

    @staticmethod
    def _segments(record, stair, label):
        y = np.asarray(record.y, float)
        if y.ndim != 1 or y.size != stair.u.size:
            raise NonlinearIdentificationError(
                f"the {label} staircase record has {y.size} samples but the staircase has {stair.u.size}; "
                "the data do not belong to this config's protocols.staircase")
        u = getattr(record, "u", None)
        if u is not None and (np.shape(u) != stair.u.shape or not np.allclose(u, stair.u)):
            raise NonlinearIdentificationError(
                f"the {label} staircase record's input differs from this config's protocols.staircase")
        if not np.all(np.isfinite(y)):
            raise NonlinearIdentificationError(f"the {label} staircase output contains NaN or inf")
        return [y[a:b] for a, b in zip(stair.starts, stair.stops)], list(stair.starts)

    def fit(self, up_record, down_record, up_staircase, down_staircase) -> "NonlinearEstimator":
        """Identify h and the borders from the two staircase records (Section 4): steady levels,
        horizontal paths, candidate fits per type and degree, selection, covariance, result."""
        self._check_settings()
        self._check_design(up_staircase, down_staircase)
        warns: list[str] = []
        data, n_up, n_dn = self._steady_levels(up_record, down_record, up_staircase, down_staircase, warns)
        j_a, j_d, z_up = self._flat_paths(data, n_up, n_dn)
        self._off_the_rails(up_record, down_record, data, n_up, warns)
        degrees, pmax_up = self._degrees(n_up, n_dn, j_a, j_d, warns)
        kinds = list(TYPES) if self.input_type == "auto" else [self.input_type]
        table = self._candidates(kinds, degrees, data, j_a, j_d, n_up)
        per_kind, pool = self._select(table, kinds, data, warns)
        kind = self._choose_type(per_kind, data.X.size)
        best = min((c for c in pool if c.kind == kind), key=lambda c: c.bic)
        self._warn_on_degree(best, pool, pmax_up, n_up - j_a, warns)
        cov, chi2, dof, gof_p = self._covariance(kind, best, data, warns)
        theta, cov, verdict = _anchored(kind, best.theta, cov, data, warns)
        evidence = self._evidence(kind, per_kind, j_a, z_up, data.X.size, data.X[:n_up], data.se[:n_up])
        self._warn_on_type(kind, per_kind, warns)
        flat_up, flat_down = self._reported_paths(kind, best, data, j_a, j_d, warns)
        V = internal_levels(kind, theta[-3], theta[-2], theta[-1], data)
        st = self.steady_
        self.result_ = self._result(kind, best.p, theta, cov, data, st, flat_up, flat_down, V, evidence, warns,
                                    {"chi2": chi2, "dof": dof, "gof_p": gof_p, "n_up": n_up,
                                     "j_a_test": j_a, "j_d_test": j_d, "overdispersion": self.c_hat_,
                                     "noise_lrv": st.lrv, "noise_df": st.df, "noise_batches": st.n_batches,
                                     "first_sample": st.first.tolist(), "n_averaged": st.n.tolist(),
                                     "selection": [{"type": c.kind, "degree": c.p, "chi2": c.chi2,
                                                    "criterion": c.bic, "type_criterion": c.qbic,
                                                    "d_plus": float(c.theta[-3]),
                                                    "slope_down": float(c.theta[-2]),
                                                    "d_minus": float(c.theta[-1]),
                                                    "other_zeros": c.other_zeros}
                                                   for c in table]})
        width = float(np.ptp(np.concatenate([up_staircase.all_levels, down_staircase.all_levels])))
        self.result_ = unread(undetermined(self.result_, width), verdict)
        r = self.result_
        self.type_, self.degree_ = r.type, r.degree
        self.d_plus_, self.slope_down_, self.d_minus_ = r.d_plus, r.slope_down, r.d_minus
        self.h_coef_ = np.asarray(r.h_coefficients)
        self.flat_up_, self.flat_down_ = r.flat_up, r.flat_down
        self.selection_ = table
        return self

    # ------------------------------------------------------------------------------ fit's steps
    @staticmethod
    def _check_design(up_staircase, down_staircase) -> None:
        """Step 0: what the staircases can determine (:mod:`hwid.identify.determinable`, as for a
        recorded history): fewer than 2 distinct levels on a branch is one line naming the
        parameters left undetermined and the levels that would determine them."""
        levels = [Level(s.name, k, float(u), 0.0, 1.0, 0, k >= s.lead_in.size)
                  for s in (up_staircase, down_staircase) for k, u in enumerate(s.all_levels)]
        why = determinable.refusal(determinable.design(levels), "stage 1 from the staircases",
                                   " (protocols.staircase.levels_up, levels_down)")
        if why:
            raise NonlinearIdentificationError(why)

    def _steady_levels(self, up_record, down_record, up_staircase, down_staircase, warns):
        """Step 1: each level's steady output and standard error (eq. 9, :mod:`hwid.identify.steady`)."""
        segments_up, offsets_up = self._segments(up_record, up_staircase, "ascending")
        segments_down, offsets_down = self._segments(down_record, down_staircase, "descending")
        try:
            st = steady_levels(segments_up + segments_down, offsets=offsets_up + offsets_down, pool=self.pool_noise)
        except ValueError as err:
            raise NonlinearIdentificationError(f"{err} (protocols.staircase.hold)") from None
        warns += st.warnings
        self.steady_ = st
        data = LevelData(np.asarray(up_staircase.all_levels, float), np.asarray(down_staircase.all_levels, float),
                         len(up_staircase.lead_in), len(down_staircase.lead_in), st.mean.copy(), st.se.copy())
        return data, len(segments_up), len(segments_down)

    def _off_the_rails(self, up_record, down_record, data, n_up: int, warns) -> None:
        """Levels whose averaged output rests on a sensor rail (:mod:`hwid.identify.rails`) read the
        rail, not ``h``: their standard error is made so large that the fit of h and the borders
        does not use them (the horizontal paths are found before, where a clipped path still reads
        one value). Through them, h bends to meet the rail: the paper's plant behind a sensor that
        clipped its ascending staircase's horizontal path was given a degree-6 h with even terms."""
        from hwid.identify.rails import find_rails
        found = find_rails([up_record.y, down_record.y])
        if not found:
            return
        st = self.steady_
        clipped = []
        for j in range(data.X.size):
            y = np.asarray((up_record if j < n_up else down_record).y, float)
            seg = y[int(st.first[j]):int(st.first[j]) + int(st.n[j])]
            if seg.size and any(np.mean(seg == r.value) > 0.5 for r in found):
                clipped.append(j)
        if not clipped or data.X.size - len(clipped) < 4:
            return
        data.se[clipped] = RAIL_SE * max(float(np.max(np.abs(data.X))), 1.0)
        warns.append(f"{len(clipped)} level(s) read the sensor's rail ({', '.join(f'{r.value:.6g}' for r in found)}): "
                     f"not used for h and the borders (levels {', '.join(str(j + 1) for j in clipped)}, ascending "
                     f"first)")

    def _flat_paths(self, data, n_up: int, n_dn: int):
        """Step 2: ``j_a``, ``j_d`` (eqs. 7a, 14a) by the sequential tests; a staircase that never
        leaves its horizontal path means the working interval is too narrow (Fig. 6a)."""
        Xu, Xd, eu, ed = data.X[:n_up], data.X[n_up:], data.se[:n_up], data.se[n_up:]
        ja_extra, z_up = flat_run(Xu[1:], eu[1:], [Xu[0]], [eu[0]], self.alpha)
        j_a = 1 + ja_extra
        j_d, _ = flat_run(Xd, ed, [Xu[-1]], [eu[-1]], self.alpha)
        lo, hi = float(min(data.U.min(), data.all_up.min())), float(max(data.U.max(), data.all_up.max()))
        if j_a >= n_up:
            raise NonlinearIdentificationError(
                f"the output never leaves the horizontal path on the ascending staircase (all {n_up} levels give "
                f"the same steady output within noise): the working interval [u_m, u_M] = [{lo:g}, {hi:g}] is too "
                "narrow to reach the backlash borders (Section 3, Fig. 6a); widen protocols.staircase levels")
        if j_d >= n_dn:
            raise NonlinearIdentificationError(
                f"the output never leaves the horizontal path on the descending staircase (all {n_dn} levels give "
                f"the same steady output within noise): the working interval [u_m, u_M] = [{lo:g}, {hi:g}] is too "
                "narrow to reach the descending border (Section 3, Fig. 6a); widen protocols.staircase levels")
        return j_a, j_d, z_up

    def _degrees(self, n_up: int, n_dn: int, j_a: int, j_d: int, warns):
        """Step 3: the degrees to try, eq. (11) (``N - j_a >= p + 1``), or the configured one."""
        n_border_up = n_up - j_a      # j_a >= 1: the first level sits on the descending border
        n_border_dn = n_dn - j_d
        if n_border_up < 2:
            raise NonlinearIdentificationError(
                f"only {n_border_up} ascending level(s) lie on the border (N - j_a = {n_up} - {j_a}): eq. (11) "
                "needs at least p + 1 >= 2; add levels above the horizontal path")
        if n_border_dn < 2:
            raise NonlinearIdentificationError(
                f"only {n_border_dn} descending level(s) lie on the border ({n_dn} levels, j_d = {j_d}): at least "
                "2 are needed for S^d and d^- (eq. 14); add levels below the horizontal path")
        pmax_up = n_border_up - 1
        if self.degree is not None:
            p = int(self.degree)
            if p > pmax_up:
                raise NonlinearIdentificationError(
                    f"the ascending staircase has N - j_a = {n_border_up} levels on the border, too few for degree "
                    f"{p}: eq. (11) needs N - j_a >= p + 1 = {p + 1}; add levels or lower "
                    "identification.nonlinear.degree")
            if p > n_border_dn - 1:
                msg = (f"the descending staircase has {n_border_dn} levels on the border, fewer than p + 1 = {p + 1} "
                       "(eq. 11 applied to eq. 14)")
                if self.method == "paper":
                    raise NonlinearIdentificationError(msg + ": the closed form cannot fit r(u); add levels, lower "
                                                       "the degree or use method: nls")
                warns.append(msg + ": S^d and d^- rest on the joint fit")
            return [p], pmax_up
        top = min(self.max_degree, pmax_up)
        if self.method == "paper":
            top = min(top, n_border_dn - 1)
            if top < 1:
                raise NonlinearIdentificationError(
                    "too few border levels on the descending staircase for the closed form; use method: nls")
        return list(range(1, top + 1)), pmax_up

    def _candidates(self, kinds, degrees, data, j_a: int, j_d: int, n_up: int) -> list:
        """Step 4: a fit per type and degree: the closed form (``paper``), or the joint NLS from the
        closed form's starts, from a grid over the borders when those leave a misfit, and from the
        degree below (nested: it never ends worse than that); degrees above eq. (11) after."""
        n = data.X.size
        table: list[_Candidate] = []
        grids: dict = {}
        for kind in kinds:
            for p in degrees:
                try:
                    routes, ja_p, jd_p = route_with_paths(kind, p, data, j_a, j_d)
                except TooFewLevels:
                    continue
                if self.method == "paper":
                    best = routes[0]
                    _, ambiguous = pick_fit(kind, [(r.theta, r.chi2) for r in routes], data)
                    # the closed form is judged on the ascending fit, as the paper does
                    ia = ascending_index(kind, ja_p, n_up)
                    _, chi2_sel = weighted_polyfit(data.U[ia], data.X[ia], data.se[ia], p)
                    crit = chi2_sel + (p + 1) * math.log(max(ia.size, 2))
                    table.append(_Candidate(kind, p, best.theta, best.chi2, crit, best, ambiguous, ja_p, jd_p))
                    continue
                fits = [nls_fit(kind, r.theta, data) for r in routes[:4]]
                dof_p = n - (p + 3)
                if dof_p > 0 and min(f[1] for f in fits) > special.chdtri(dof_p, 1e-3):
                    if kind not in grids:
                        grids[kind] = grid_V(kind, data)
                    fits += [nls_fit(kind, th, data) for th in grid_starts(kind, p, data, grids[kind])]
                below = [c for c in table if c.kind == kind and c.p == p - 1 and np.isfinite(c.chi2)]
                if below and min(f[1] for f in fits) > below[0].chi2:
                    fits.append(nls_fit(kind, one_degree_up(below[0].theta), data))
                i, ambiguous = pick_fit(kind, fits, data)
                theta, chi2 = fits[i]
                table.append(_Candidate(kind, p, theta, chi2, chi2 + (p + 3) * math.log(n), routes[0], ambiguous,
                                        ja_p, jd_p))
            if self.method == "nls" and self.degree is None:
                table += self._beyond_eq11(kind, [c for c in table if c.kind == kind], data, grids)
        if not table:
            raise NonlinearIdentificationError("no model could be fitted to the staircase data")
        return table

    def _select(self, table, kinds, data, warns):
        """Step 5: the admissible fits and the best of each type.

        Remark 1.3: ``h(w) = 0`` only at ``w = 0`` is what makes the borders identifiable, so a fit
        whose h crosses zero elsewhere where the data go is set aside while one that keeps it
        exists. When even the best fit leaves a misfit (chi2/dof >> 1), chi^2 differences are
        inflated by ``c = chi2/dof`` and the type is compared by ``chi2/c`` (quasi-likelihood BIC,
        Burnham & Anderson 2002, Sec. 2.5). Returns ``(per_kind, pool)``."""
        n = data.X.size
        self.c_hat_ = 1.0
        pool = [c for c in table if np.isfinite(c.chi2)]
        for c in pool:
            c.other_zeros = other_zeros(c.kind, c.theta, data)
        admissible = [c for c in pool if c.other_zeros == 0]
        if admissible and len(admissible) < len(pool):
            warns.append(f"{len(pool) - len(admissible)} fit(s) whose h has another zero where the data go (Remark 1.3 "
                         "needs h(w) = 0 only at w = 0) were set aside")
            pool = admissible
        if self.method == "nls":
            c_hat = overdispersion(pool, n)
            if c_hat is not None:
                self.c_hat_ = float(c_hat)
        for c in pool:
            c.qbic = c.chi2 / self.c_hat_ + (c.p + 3) * math.log(n) if self.method == "nls" else c.bic
        per_kind = {}
        for kind in kinds:
            cands = [c for c in pool if c.kind == kind]
            if cands:
                per_kind[kind] = min(cands, key=lambda c: c.qbic)
        if not per_kind:
            raise NonlinearIdentificationError("every fit of the staircase data failed (non-finite chi-square)")
        return per_kind, pool

    def _choose_type(self, per_kind, n: int) -> str:
        """Step 6: the type by the (quasi-likelihood) BIC of its best fit; for the closed forms, by the
        joint chi^2 they leave. The degree within the type is then chosen by the plain BIC: a misfit
        is structured, not noise, and a higher degree follows it where the data go."""
        if self.method == "paper":
            return min(per_kind, key=lambda k: per_kind[k].chi2 + (per_kind[k].p + 3) * math.log(n))
        return min(per_kind, key=lambda k: per_kind[k].qbic)

    def _warn_on_degree(self, best, pool, pmax_up: int, n_border_up: int, warns) -> None:
        p = best.p
        if self.degree is None and p == pmax_up and p < self.max_degree and not any(c.p > p for c in pool):
            warns.append(f"the selected degree p = {p} is the highest the N - j_a = {n_border_up} ascending border "
                         "levels support (eq. 11); a higher degree could not be tested: add levels to check it")
        elif p > pmax_up:
            warns.append(f"the selected degree p = {p} is above the {pmax_up} that the N - j_a = {n_border_up} "
                         "ascending border levels support alone (eq. 11): it rests on the joint fit of both "
                         "staircases; add ascending levels to check it")
        if best.ambiguous:
            warns.append("several roots of the fitted h(u - d^+) give equally good models whose h has no other zero "
                         "in the working range: d^+ is ambiguous (Remark 1.3 needs h(w) = 0 only at w = 0)")

    def _covariance(self, kind, best, data, warns):
        """Step 7: the covariance of ``theta``, ``(J^T W J)^-1`` (nls) or the delta method through the
        closed form (paper), widened by ``chi2/dof`` when the joint fit misfits."""
        p, theta = best.p, best.theta
        dof = data.X.size - (p + 3)
        if self.method == "nls":
            cov = nls_cov(kind, theta, data)
        else:
            cov = self._paper_cov(kind, p, data, best.j_a, best.j_d, best.route.a, best.route.b)
        chi2 = joint_chi2(kind, theta, data)
        gof_p = float(special.chdtrc(dof, chi2)) if dof > 0 else float("nan")
        if self.method == "nls" and dof > 0 and gof_p < 1e-3:
            warns.append(f"the model does not fit the staircase data within their standard errors (chi2 = {chi2:.4g} "
                         f"for {dof} dof, p = {gof_p:.1g}): h may not be a polynomial of degree <= {p} on this range, "
                         "or a level did not settle; intervals are widened by sqrt(chi2/dof)")
            cov = cov * (chi2 / dof)
        return cov, chi2, dof, gof_p

    def _warn_on_type(self, kind, per_kind, warns) -> None:
        if len(per_kind) == 2:
            other = [k for k in per_kind if k != kind][0]
            delta = per_kind[other].qbic - per_kind[kind].qbic if self.method == "nls" else \
                per_kind[other].chi2 - per_kind[kind].chi2
            if delta < 10:
                warns.append(f"the data barely distinguish Backlash from Backlash-Inverse (delta = {delta:.3g} < 10); "
                             "widen the working interval or add levels")

    def _reported_paths(self, kind, best, data, j_a: int, j_d: int, warns) -> tuple[int, int]:
        """Step 8: the horizontal paths reported: those the chosen fit used (Backlash), none for a
        Backlash-Inverse (Remark 1.4); disagreements with the tests and the fitted borders warned."""
        if kind != "backlash":
            return 0, 0
        if (best.j_a, best.j_d) != (j_a, j_d):
            warns.append(f"the flat-path tests gave j_a = {j_a}, j_d = {j_d}; the borders fit best and agree with "
                         f"j_a = {best.j_a}, j_d = {best.j_d}, which are reported")
        j_a, j_d = best.j_a, best.j_d
        ja_model, jd_model = path_memberships(kind, best.theta, data)
        if (ja_model, jd_model) != (j_a, j_d):
            warns.append(f"the tests put j_a = {j_a}, j_d = {j_d}; the fitted borders put j_a = {ja_model}, "
                         f"j_d = {jd_model} (a level lies within noise of the horizontal path)")
        return j_a, j_d

    def _beyond_eq11(self, kind, done, data, grids) -> list:
        """Degrees above eq. (11)'s limit, for the joint fit only, while the highest degree fitted
        still misfits (chi2 p < 1e-3).

        Eq. (11) bounds ``p`` by the ascending border levels because the closed form fits ``h``
        on them alone; the joint fit also sees the descending border, whose levels sample ``h`` at
        other ``w``. When the borders leave few ascending levels (a deadzone or a bent border moving
        a level onto the horizontal path), a quintic ``h`` was cut to degree 4 and every later stage
        inherited the misfit. Each further degree starts from the one below (``c_p = 0``) and from
        the grid of :func:`grid_starts`, and is kept while its coefficient is significant by the F
        test of nested fits (level ``alpha``; the scale is the misfit, chi2/dof: a level that did not
        settle made BIC add four degrees for a drop of chi2 from 73 to 34, and the degree-9 ``h``
        extrapolated wildly); at most ``max_degree``, and ``n - p - 3 >= 2`` dof."""
        out: list[_Candidate] = []
        n = data.X.size
        if not done:
            return out
        last = max(done, key=lambda c: c.p)
        while True:
            p = last.p + 1
            dof_last = n - (last.p + 3)
            if p > self.max_degree or n - (p + 3) < 2 or not np.isfinite(last.chi2) \
                    or last.chi2 <= special.chdtri(dof_last, 1e-3):
                return out
            if kind not in grids:
                grids[kind] = grid_V(kind, data)
            starts = [one_degree_up(last.theta)] + grid_starts(kind, p, data, grids[kind])
            fits = [nls_fit(kind, th, data) for th in starts]
            i, amb = pick_fit(kind, fits, data)
            theta, chi2 = fits[i]
            # the added coefficient must be significant by the F test of nested fits, whose scale is
            # the misfit itself (chi2 / dof), not the noise: under a misfit BIC takes any small drop
            dof = n - (p + 3)
            if not (np.isfinite(chi2) and chi2 < last.chi2
                    and special.fdtrc(1, dof, (last.chi2 - chi2) / max(chi2 / dof, 1e-300)) < self.alpha):
                return out
            last = _Candidate(kind, p, theta, chi2, chi2 + (p + 3) * math.log(n), last.route, amb, last.j_a, last.j_d)
            out.append(last)

    def _paper_cov(self, kind, p, data, j_a, j_d, a, b) -> np.ndarray:
        """Delta method through the closed form: ``J diag(se^2) J^T`` with ``J = d theta / d X_hat``."""
        def theta_of(X):
            return paper_route(kind, p, data.with_X(X), j_a, j_d, a_ref=a, b_ref=b)[0].theta
        J = []
        for k in range(data.X.size):
            h = 1e-3 * data.se[k]
            Xp, Xm = data.X.copy(), data.X.copy()
            Xp[k] += h
            Xm[k] -= h
            J.append((theta_of(Xp) - theta_of(Xm)) / (2 * h))
        J = np.column_stack(J)
        return J @ np.diag(data.se ** 2) @ J.T

    def _evidence(self, kind, per_kind, j_a, zu, n, Xu, eu) -> str:
        parts = []
        if j_a >= 2:
            x, s = Xu[:j_a], eu[:j_a]
            w = 1 / s ** 2
            m = np.sum(w * x) / np.sum(w)
            q = float(np.sum(w * (x - m) ** 2))
            pv = float(special.chdtrc(j_a - 1, q))
            parts.append(f"X_1..X_{j_a} of the ascending staircase lie on one horizontal path (homogeneity "
                         f"chi2 = {q:.3g} on {j_a - 1} dof, p = {pv:.2g}), which only a Backlash produces")
        else:
            parts.append(f"no horizontal path: X_2 differs from X_1 (z = {zu[0]:.3g})" if zu else "no horizontal path")
        fits = "; ".join(f"{k}: chi2 = {c.chi2:.4g} for {n - c.p - 3} dof at degree {c.p}"
                         for k, c in per_kind.items())
        parts.append(f"joint fit {fits}")
        if len(per_kind) == 2:
            other = [k for k in per_kind if k != kind][0]
            if self.method == "nls":
                parts.append(f"BIC prefers {kind} by {per_kind[other].qbic - per_kind[kind].qbic:.4g}")
            else:
                parts.append(f"the closed form's joint chi2 prefers {kind} by "
                             f"{per_kind[other].chi2 - per_kind[kind].chi2:.4g}")
        else:
            parts.append(f"type fixed to {kind} by identification.nonlinear.input_type")
        return f"{kind}: " + "; ".join(parts)

    def _result(self, kind, p, theta, cov, data, st: SteadyLevels, flat_up, flat_down, V, evidence, warns, fit):
        df = max(int(st.df), 1)
        tq = float(special.stdtrit(df, 0.5 + self.confidence / 2))
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        names = tuple(f"c{i}" for i in range(1, p + 1)) + ("d_plus", "slope_down", "d_minus")
        iv = {nm: (float(theta[i] - tq * sd[i]), float(theta[i] + tq * sd[i])) for i, nm in enumerate(names)}
        # slope_up and h_bar's constant are fixed by the normalisation (eqs. 4a-c): no interval
        ci = {"slope_up": None, "slope_down": iv["slope_down"], "d_plus": iv["d_plus"],
              "d_minus": iv["d_minus"],
              "h_coefficients": [None] + [iv[f"c{i}"] for i in range(1, p + 1)],
              "X_hat": [(float(x - tq * s), float(x + tq * s)) for x, s in zip(data.X, data.se)]}
        fit = dict(fit, t_quantile=tq, confidence=self.confidence, param_se=sd.tolist())
        return NonlinearResult(
            type=kind, slope_up=1.0, slope_down=float(theta[-2]), d_plus=float(theta[-3]), d_minus=float(theta[-1]),
            h_coefficients=(0.0,) + tuple(float(c) for c in theta[:p]), degree=int(p),
            w_range=(float(V.min()), float(V.max())), ci=ci, cov=np.asarray(cov, float), param_names=names,
            levels=tuple(float(u) for u in data.U), X_hat=tuple(float(x) for x in data.X),
            X_hat_se=tuple(float(s) for s in data.se), flat_up=int(flat_up), flat_down=int(flat_down),
            method=self.method, evidence=evidence, warnings=tuple(dict.fromkeys(warns)), fit=fit)


def undetermined(res: NonlinearResult, width: float) -> NonlinearResult:
    """``res`` with every estimate whose interval cannot stand as one
    (:func:`hwid.identify.determinable.interval_flaw`: not finite, of zero width, a border's wider
    than the input range ``width`` the staircases explore, a slope's reaching zero) reported as
    undetermined: interval None and the reason, one warning line each; and the fit's adequacy where
    no degree of freedom is left to judge it."""
    why = {}
    for name in ("d_plus", "d_minus", "slope_down"):
        flaw = determinable.interval_flaw(getattr(res, name), res.ci[name],
                                          None if name == "slope_down" else width, positive=name == "slope_down")
        if flaw:
            why[name] = flaw
    for i, (c, interval) in enumerate(zip(res.h_coefficients, res.ci["h_coefficients"])):
        flaw = determinable.interval_flaw(c, interval) if i else None
        if flaw:
            why[f"c{i}"] = flaw
    dof = int(res.fit.get("dof", 1))
    if dof < 1:
        why["adequacy"] = (f"{len(res.levels)} levels for {res.degree + 3} parameters: the model passes through "
                           "every level, so its chi-square cannot judge it; add levels to either staircase")
    if not why:
        return res
    ci = dict(res.ci)
    for name in ("d_plus", "d_minus", "slope_down"):
        if name in why:
            ci[name] = None
    ci["h_coefficients"] = [None if f"c{i}" in why else v for i, v in enumerate(res.ci["h_coefficients"])]
    warns = tuple(dict.fromkeys(list(res.warnings) + [f"undetermined {k}: {v}" for k, v in why.items()]))
    return replace(res, ci=ci, warnings=warns, undetermined={**res.undetermined, **why})


def _anchored(kind: str, theta, cov, data: LevelData, warns: list):
    """``(theta, cov, verdict)``: the fit moved to the reading the paper's assumption ``h^-1(0) = 0``
    picks among h_bar's root-shifted readings (:func:`hwid.identify.readings.assess`, on the range
    of the levels' ``V_j`` after the lead-ins), its covariance carried along
    (:func:`hwid.identify.readings.transform`); one warning line for a move.

    The staircases' model starts F below every border (:data:`hwid.model.BELOW_BORDERS`) and lets
    the lead-in place it, so every level's ``V_j`` follows the borders: a shift to another root of
    h_bar is exactly equivalent (the plant's own start at rest anchors nothing, since the lead-in's
    first level wipes it out); a reading whose chi-square is more than 3.84 above (it is not, for
    an exact shift) is not a rival."""
    V = internal_levels(kind, theta[-3], theta[-2], theta[-1], data)
    U = data.U
    width = float(np.ptp(U)) or 1.0
    chi2 = joint_chi2(kind, theta, data)

    def params(r):
        return np.concatenate([r.h_coefficients[1:], [r.d_plus, r.slope_down, r.d_minus]])

    verdict = readings.assess(
        kind, theta[-2], theta[-3], theta[-1], np.concatenate([[0.0], theta[:-3]]), (float(V.min()), float(V.max())),
        admissible=lambda r: all(U.min() - width <= d <= U.max() + width for d in (r.d_plus, r.d_minus)),
        alike=lambda r: joint_chi2(kind, params(r), data) <= chi2 + special.chdtri(1, 0.05))
    if not verdict.shifted:
        return theta, cov, verdict
    warns.append(verdict.note(float(theta[-3])))
    moved, cov = readings.transform(kind, theta, cov, verdict.chosen.shift)
    return moved, cov, verdict


def unread(res: NonlinearResult, verdict) -> NonlinearResult:
    """``res`` with the borders and h_bar undetermined where h_bar's root-shifted readings leave them
    open (:meth:`hwid.identify.readings.Verdict.undetermined`), the readings with their intervals in
    ``readings``; unchanged where the reading is determined."""
    if verdict.determined:
        return res
    why = {k: v for k, v in verdict.undetermined().items() if k != "dead_band"}
    params = np.concatenate([res.h_coefficients[1:], [res.d_plus, res.slope_down, res.d_minus]])
    ci = {**res.ci, "d_plus": None, "d_minus": None, "h_coefficients": [None] * len(res.ci["h_coefficients"])}
    warns = tuple(dict.fromkeys(list(res.warnings) + determinable.warning_lines(why)))
    return replace(res, ci=ci, warnings=warns, undetermined={**res.undetermined, **why},
                   readings=tuple(verdict.to_dicts(res.type, params, res.cov,
                                                   float(res.fit.get("t_quantile", 1.959963984540054)))))


# ------------------------------------------------------------------------------------ run

def _records_from(data, up, down) -> tuple[Any, Any]:
    """The two staircase records from a ``simulation.h5`` path or a mapping name -> Record."""
    recs = read_experiments(data, ("simulation", "nonlinear")) if isinstance(data, (str, Path)) else dict(data)
    if isinstance(data, (str, Path)) and not recs:
        raise NonlinearIdentificationError(f"{data}: holds no experiments")
    missing = [s.name for s in (up, down) if s.name not in recs]
    if missing:
        raise NonlinearIdentificationError(
            f"{data if isinstance(data, (str, Path)) else 'the data'} hold no experiment "
            f"{' or '.join(repr(m) for m in missing)}; run hwid simulate with a config that has protocols.staircase")
    return recs[up.name], recs[down.name]


def identify_nonlinear(cfg, plant=None, data=None, journal_dir=None):
    """Stage 1 on the config's staircases: run them on ``plant`` (default: the config's plant) or read
    them from ``data`` (a ``simulation.h5`` path or a mapping of records); return ``(result, records)``."""
    from hwid import protocols
    if cfg.protocols.staircase is None:
        raise NonlinearIdentificationError(
            "the config has no protocols.staircase: stage 1 needs the ascending and descending staircases (Section 4)")
    up, down = protocols.staircases(cfg)
    if data is not None:
        ru, rd = _records_from(data, up, down)
    else:
        if plant is None:
            from hwid.plant import make_plant
            plant = make_plant(cfg, journal_dir=journal_dir)
        ru = plant.run(up.name, up.u)
        rd = plant.run(down.name, down.u)
        for r, s in ((ru, up), (rd, down)):
            r.attrs.update({"direction": s.direction, "hold": s.hold, "levels": s.levels.tolist(),
                            "lead_in": s.lead_in.tolist()})
    est = NonlinearEstimator.from_config(cfg).fit(ru, rd, up, down)
    return est.result_, [ru, rd]
