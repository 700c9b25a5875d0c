"""Stage 2: the linear subsystem G(j omega) behind the pre-compensator (paper Section 5, Fig. 8).

For each frequency of ``protocols.sine`` the pre-compensator built from the *estimated normalised*
input nonlinearity (stage 1) turns ``z = U sin(omega t)`` (eq. 15) into ``v ~ z`` (eq. 16), so that in
normalised units ``x = h(G * z)`` (eqs. 17-18, ``G(0) = 1``). From the steady-state output the
harmonic coefficients ``C_k`` are fitted by least squares (:mod:`hwid.identify.harmonics`,
eqs. 23-26) and ``|G|``, ``phi = -arg G`` are estimated with the harmonic model of eq. (20):

* ``method="nls"`` (default): weighted nonlinear least squares of ``C_k = D_k(U|G|) e^{-jk phi}`` over
  every harmonic the model predicts: the maximum-likelihood estimate under Gaussian noise; 95 %
  intervals from the Fisher information (which, evaluated at the estimate, is the Cramer-Rao bound,
  :mod:`hwid.identify.crlb`).
* ``method="paper"``: eq. (37) generalised to any harmonic ``k`` and any polynomial: ``|G|`` from
  ``|D_k(U|G|)| = s_k`` (the root that best explains the other harmonics when ``k < p``), and
  ``phi = (arg D_k - psi_k)/k + 2 pi m / k`` with the k-fold ambiguity ``m`` resolved by the other
  harmonics (the fundamental pins it). Intervals by the delta method.

Two small effects are divided out of the measured fundamental of ``w`` (both recorded per frequency):
the zero-order hold of the sampled input (``(1 - e^{-j omega dt})/(j omega dt)``, a delay of dt/2 that
is several standard errors at 0.2 rad/s in the paper's setting; ``hold_correction``) and what is left
of the input nonlinearity after the pre-compensator as the *model* predicts it (``F_hat[P_hat(z)]``:
exactly z for a Backlash plant, one switching sample per reversal for a Backlash-Inverse plant).

The measurement offset is treated as an unknown nuisance parameter (a real sensor has one), so the
mean ``s_0`` carries no information about G and is left out of both estimators and of the bound.
"""
from __future__ import annotations

import warnings
from typing import Optional

import numpy as np
from numba import njit
from scipy import special

from hwid import HwidError
from hwid.identify.crlb import crlb
from hwid.identify.known import KnownNonlinear
from hwid.identify.harmonics import (DistortedHarmonics, HarmonicFit, HarmonicModel, distorted_harmonics,
                                     fit_harmonics, period_sums, span_projector)
from hwid.identify.lm import lm
from hwid.identify.rails import find_rails
from hwid.identify.result import LinearResult
from hwid.identify.sine_runs import run_sines


@njit(cache=True)
def _all_close(a, b, atol):
    """``np.allclose(a, b, rtol=0, atol=atol)`` for finite ``b``, in one pass without temporaries."""
    for i in range(a.shape[0]):
        if not abs(a[i] - b[i]) <= atol:
            return False
    return True


class ExtrapolationWarning(UserWarning):
    """``U |G|`` drives ``w`` outside the range over which ``h`` was identified (stage 1)."""


def _wrap(phi):
    """To ``(-pi, pi]``."""
    return float(np.pi - np.mod(np.pi - phi, 2 * np.pi))


# ---------------------------------------------------------------------------------------- the estimator

class LinearEstimator:
    """Estimate ``G(j omega)`` from one sine experiment (Section 5).

    Parameters
    ----------
    method : {"nls", "paper"}
        Weighted NLS over all harmonics (ML), or eq. (37) with one harmonic.
    harmonic : int, optional
        The harmonic of ``method="paper"`` (default: the highest significant one).
    k_max : int, optional
        Highest harmonic fitted by least squares (default ``p + 2``, below Nyquist).
    confidence : float
        Level of the intervals.
    hold_correction : bool
        Divide out the zero-order hold of the sampled input.
    noise_model : {"auto", "white", "periodic"}
        See :func:`hwid.identify.harmonics.fit_harmonics`.
    propagate_stage1 : bool
        In :func:`estimate_response`, widen the intervals by the stage 1 uncertainty
        (:meth:`add_stage1_uncertainty`) when the stage 1 result carries ``cov``.

    Attributes
    ----------
    gain_, phase_ : float
        ``|G_hat(j omega)|`` and ``phi_hat = -arg G_hat`` (rad, wrapped to (-pi, pi]).
    gain_ci_, phase_ci_ : tuple
        Intervals at ``confidence``.
    cov_ : ndarray (2, 2)
        Covariance of ``(gain, phase)``.
    crlb_ : tuple
        Cramer-Rao bound on the variances at the estimate, with the estimated noise.
    estimates_ : dict
        Both estimators' results (``"nls"`` and ``"paper"``), each ``gain, phase, cov, ...``.
    harmonics_ : HarmonicFit
    input_correction_ : complex
        ``kappa``: the measured fundamental of ``w`` is ``U kappa G(j omega)``.
    extrapolated_ : bool
    warnings_ : list of str
    """

    def __init__(self, method: str = "nls", harmonic: Optional[int] = None, k_max: Optional[int] = None,
                 confidence: float = 0.95, hold_correction: bool = True, noise_model: str = "auto",
                 propagate_stage1: bool = True):
        self.method = method
        self.harmonic = harmonic
        self.k_max = k_max
        self.confidence = confidence
        self.hold_correction = hold_correction
        self.noise_model = noise_model
        self.propagate_stage1 = propagate_stage1

    # -- helpers
    def _quantile(self, dof: float) -> float:
        a = 0.5 + self.confidence / 2
        return float(special.ndtri(a) if not np.isfinite(dof) else special.stdtrit(dof, a))

    def _input_correction(self, record, sine, nonlinear, hf: HarmonicFit, k_dist: int):
        """``kappa`` (fundamental of ``F_hat[u]`` over ``U``, times the hold), the distortion (rms of the
        other harmonics over the fundamental) and the coefficients ``V_0..V_K`` of ``F_hat[u]``."""
        kappa = 1.0 + 0j
        thd = 0.0
        V = None
        u = getattr(record, "u", None)
        if u is not None and nonlinear is not None:
            v = np.asarray(nonlinear.input_nonlinearity().apply(np.asarray(u, float)), float)
            if not _all_close(v, np.ascontiguousarray(sine.z[: v.size]), 1e-12 * max(1.0, sine.amplitude)):
                S = period_sums(v, record.dt, sine.omega, k_dist)
                used = slice(hf.first_period, hf.first_period + hf.periods)
                th = np.linalg.solve(S.XtX[used].sum(0), S.Xty[used].sum(0))
                V = np.concatenate([[th[0]], th[k_dist + 1:] + 1j * th[1:k_dist + 1]])
                kappa = complex(V[1] / sine.amplitude)
                thd = float(np.sqrt(np.sum(np.abs(V[2:]) ** 2) + V[0].real ** 2) / abs(V[1]))
        if self.hold_correction:
            kappa *= self._hold(sine.omega, record.dt)
        return complex(kappa), thd, V

    @staticmethod
    def _hold(omega, dt):
        x = np.asarray(omega, float) * dt
        return (1 - np.exp(-1j * x)) / (1j * x)

    def fit(self, record, sine, nonlinear, g_model=None) -> "LinearEstimator":
        """Fit one sine experiment.

        Parameters
        ----------
        record : hwid.plant.Record
            The experiment (``y`` from the start of the sine; ``u`` the pre-compensated input).
        sine : hwid.protocols.Sine
            The sine of eq. (15) that was pre-compensated.
        nonlinear : NonlinearLike
            Stage 1 result: ``h_coefficients``, ``w_range``, ``input_nonlinearity()``.
        g_model : callable, optional
            ``omega -> G(j omega)`` (e.g. a first-pass parametric fit). When the pre-compensated input
            is not a pure sine (a Backlash-Inverse plant: one switching sample per reversal), its other
            harmonics ``V_k`` reach ``w`` as ``G(j k omega) V_k`` and mix in ``h``; with ``g_model``
            that distortion is put into the harmonic model (computed numerically) and the NLS estimate
            is freed of its bias.
        """
        if self.method not in ("nls", "paper"):
            raise ValueError(f"method must be 'nls' or 'paper', got {self.method!r}")
        if not 0 < self.confidence < 1:
            raise ValueError("confidence must be in (0, 1)")
        y = np.asarray(record.y, float)
        dt, omega = float(record.dt), float(sine.omega)
        p = len(tuple(nonlinear.h_coefficients)) - 1
        if p < 1:
            raise ValueError("h must have degree >= 1")
        spp = 2 * np.pi / omega / dt
        k_cap = max(1, min(int(np.floor((np.pi / dt) / omega - 1e-9)), int((spp - 1) // 2)))
        k_max = min(self.k_max or p + 2, k_cap)
        self._record, self._sine, self._k_cap, self._k_max = record, sine, k_cap, k_max
        self.data_warnings_ = []

        hf = fit_harmonics(y, dt, omega, k_max, first_period=sine.lead_in_periods, noise_model=self.noise_model)
        self.harmonics_ = hf
        if hf.first_period > sine.lead_in_periods:
            self.data_warnings_.append(f"omega = {omega:g} rad/s: the response was not yet periodic after the "
                                       f"{sine.lead_in_periods} lead-in periods; "
                                       f"{hf.first_period - sine.lead_in_periods} more discarded")
        if hf.steady_p < 1e-3:
            self.data_warnings_.append(f"omega = {omega:g} rad/s: no steady state reached (the first used period "
                                       f"still differs from the late ones, p = {hf.steady_p:.2g}); add lead-in "
                                       f"periods")
        if hf.periodicity_p < 1e-3:
            self.data_warnings_.append(f"omega = {omega:g} rad/s: the response is not periodic (first half of the "
                                       f"periods differs from the second, p = {hf.periodicity_p:.2g})")
        for rail in find_rails([y]):
            self.data_warnings_.append(f"omega = {omega:g} rad/s: the output rests on the sensor's {rail.side} rail "
                                       f"({rail.value:.6g}) for {rail.samples} samples: these harmonics are a "
                                       f"clipped output's, not h(G w)'s; lower protocols.sine.amplitude")
        return self.refit(nonlinear, g_model)

    def _distortion(self, V, g_model):
        """``W``: the distortion of w, ``d = V_0 G(0) + sum_{k>=2} Im(V_k H(k omega) G(j k omega) e^{jk omega t})``."""
        if V is None or g_model is None:
            return None
        omega, dt = self._sine.omega, self._record.dt
        kk = np.arange(2, V.size)
        W = np.zeros(V.size, dtype=complex)
        W[0] = V[0].real
        hold = self._hold(kk * omega, dt) if self.hold_correction else 1.0
        W[2:] = V[2:] * hold * np.asarray(g_model(kk * omega), complex)
        return W

    def _tail_input(self, nonlinear):
        """``kappa`` and ``V`` of ``F_hat[u]`` from the last used period only (cheap; for derivatives)."""
        rec, sine, hf = self._record, self._sine, self.harmonics_
        T, dt = sine.period, rec.dt
        last = hf.first_period + hf.periods - 1
        a, b = int(np.ceil(last * T / dt - 1e-9)), int(np.ceil((last + 1) * T / dt - 1e-9))
        a0 = max(0, a - (b - a))
        v = np.asarray(nonlinear.input_nonlinearity().apply(np.asarray(rec.u[a0:b], float)), float)[a - a0:]
        K = max(1, min(15, self._k_cap))
        if getattr(self, "_tail_fit", None) is None or self._tail_fit[0] != (a, b, K):
            self._tail_fit = ((a, b, K), span_projector(a, b, sine.omega, dt, K))
        th = self._tail_fit[1](v)
        V = np.concatenate([[th[0]], th[K + 1:] + 1j * th[1:K + 1]])
        kappa = complex(V[1] / sine.amplitude)
        if self.hold_correction:
            kappa *= self._hold(sine.omega, dt)
        return kappa, V

    def _point(self, nonlinear, g_model, ks, c, var, sig, kappa, V, x0=None) -> dict:
        """Both estimators for one (nonlinear, input) hypothesis."""
        hm = HarmonicModel(tuple(nonlinear.h_coefficients))
        U = float(self._sine.amplitude)
        rho, th_k = U * abs(kappa), float(np.angle(kappa))
        W = self._distortion(V, g_model) if V is not None else None

        def cost(g, phi, D=None):
            D = hm.D(rho * g, ks) if D is None else D          # D: hm.D(rho * g, ks), computed by the caller
            return float(np.sum(np.abs(c - D * np.exp(-1j * ks * (phi - th_k))) ** 2 / var))

        est = {"nls": self._nls(hm, ks, c, var, rho, th_k, W, x0), "paper": None}
        try:
            est["paper"] = self._paper(hm, ks, c, var, rho, th_k, cost, sorted(sig))
        except HwidError as err:
            if self.method == "paper":
                raise
            est["paper"] = {"error": str(err)}
        return est, hm, rho, th_k, W

    def refit(self, nonlinear, g_model=None) -> "LinearEstimator":
        """Re-estimate from the stored harmonic fit with another stage 1 result or ``g_model``."""
        hf, sine, record = self.harmonics_, self._sine, self._record
        omega, U = float(sine.omega), float(sine.amplitude)
        self.warnings_ = list(self.data_warnings_)
        hm = HarmonicModel(tuple(nonlinear.h_coefficients))
        k_max = self._k_max
        k_dist = max(1, min(15, self._k_cap))
        kappa, thd, V = self._input_correction(record, sine, nonlinear, hf, k_dist)
        self.input_correction_ = kappa
        self.input_distortion_ = thd
        if V is not None and g_model is None:
            V = None          # the distortion needs G at the harmonics: left out of this pass
        if thd > 1e-2:
            self.warnings_.append(
                f"omega = {omega:g} rad/s: the input after F_hat is not a pure sine (model-predicted "
                f"distortion {100 * thd:.2g} %); " + ("its harmonics are modelled through the first-pass "
                                                     "G(s)" if V is not None else "G is biased by its harmonics"))

        ks_all = hm.relevant()
        ks = ks_all[ks_all <= k_max]
        if ks.size == 0:
            raise HwidError(f"omega = {omega:g} rad/s: no harmonic of h is below the Nyquist frequency")
        c, var = hf.coef[ks - 1], hf.var[ks - 1]
        sig = set(hf.significant().tolist()) & set(ks.tolist())
        if not sig:
            self.warnings_.append(f"omega = {omega:g} rad/s: no harmonic is significantly above the noise; "
                                  f"G is not determined (raise U or the number of periods)")
        self.used_harmonics_ = ks
        self.significant_harmonics_ = np.array(sorted(sig), dtype=int)
        est, hm, rho, th_k, W = self._point(nonlinear, g_model, ks, c, var, sig, kappa, V)
        self.distortion_ = W
        for e in est.values():
            if e and "gain" in e:
                e["phase"] = _wrap(e["phase"])
                e["cov_noise"] = np.asarray(e["cov"])
        self.estimates_ = est
        self._ctx = (ks, c, var, sig, g_model)
        self._set_intervals()
        chosen = est[self.method]
        self.crlb_ = crlb(hm.h_coefficients, U, self.gain_, self.phase_, hf.sigma, hf.n_samples, ks,
                          abs(kappa), component_var=var)
        self.predicted_ = hm.D(rho * self.gain_, ks) * np.exp(-1j * ks * (self.phase_ - th_k)) if W is None \
            else distorted_harmonics(hm, rho * self.gain_, self.phase_ - th_k, W, ks)[0]

        # -- extrapolation of h beyond the staircases' range (stage 1)
        lo, hi = (float(x) for x in nonlinear.w_range)
        r = rho * chosen["gain"]
        self.w_amplitude_ = r
        self.extrapolated_ = bool(-r < lo - 1e-12 or r > hi + 1e-12)
        if self.extrapolated_:
            msg = (f"omega = {omega:g} rad/s: U|G| = {r:.3g} drives w over [{-r:.3g}, {r:.3g}], outside "
                   f"[{lo:.3g}, {hi:.3g}] where h was identified; h is extrapolated there")
            self.warnings_.append(msg)
            warnings.warn(msg, ExtrapolationWarning, stacklevel=3)
        return self

    def _set_intervals(self):
        q = self._quantile(self.harmonics_.dof)
        for e in self.estimates_.values():
            if e and "gain" in e:
                se = np.sqrt(np.diag(e["cov"]))
                e["gain_ci"] = (e["gain"] - q * se[0], e["gain"] + q * se[0])
                e["phase_ci"] = (e["phase"] - q * se[1], e["phase"] + q * se[1])
        chosen = self.estimates_[self.method]
        self.gain_, self.phase_ = chosen["gain"], chosen["phase"]
        self.cov_ = np.asarray(chosen["cov"])
        self.gain_ci_, self.phase_ci_ = chosen["gain_ci"], chosen["phase_ci"]

    def add_stage1_uncertainty(self, nonlinear, g_model=None, step: float = 0.5) -> "LinearEstimator":
        """Widen the covariances by the stage 1 uncertainty (two-step estimator, delta method).

        ``cov = cov_noise + J S J^T`` with ``S = nonlinear.cov`` over ``nonlinear.param_names``
        (``c1..cp, d_plus, slope_down, d_minus``) and ``J = d(|G|, phi) / d(stage 1)`` by central
        differences of ``+-step`` standard deviations: each perturbed stage 1 changes h in eq. (20)
        and, through ``F_hat[u]`` for the fixed pre-compensated ``u``, the input the model assumes
        (``kappa`` and the distortion). The two experiments' noises are independent, so the terms add.
        """
        S = np.asarray(getattr(nonlinear, "cov", None) if getattr(nonlinear, "cov", None) is not None else [],
                       float)
        names = tuple(getattr(nonlinear, "param_names", ()) or ())
        if S.size == 0 or S.shape != (len(names), len(names)) or not np.all(np.isfinite(S)):
            return self
        from hwid.model import InputNonlinearity
        F = nonlinear.input_nonlinearity()
        base = {"d_plus": F.d_plus, "slope_down": F.slope_down, "d_minus": F.d_minus}
        h0 = list(nonlinear.h_coefficients)
        ks, c, var, sig, _ = self._ctx

        def variant(name, delta):
            h = list(h0)
            par = dict(base)
            if name.startswith("c") and name[1:].isdigit():
                i = int(name[1:])
                if i >= len(h):
                    return None
                h[i] += delta
            elif name in par:
                par[name] += delta
            else:
                return None
            if par["slope_down"] <= 0 or par["d_plus"] <= par["d_minus"]:
                return None
            return KnownNonlinear(InputNonlinearity(F.type, 1.0, par["slope_down"], par["d_plus"], par["d_minus"]),
                                  tuple(h), nonlinear.w_range)

        x_ref = np.array([self.estimates_["nls"]["gain"], self.estimates_["nls"]["phase"]])

        def point(nl):
            kappa, V = self._tail_input(nl)
            Vm = V if g_model is not None else None
            e, *_ = self._point(nl, g_model, ks, c, var, sig, kappa, Vm, x0=x_ref)
            return {m: (np.array([e[m]["gain"], e[m]["phase"]]) if e.get(m) and "gain" in e[m] else None)
                    for m in ("nls", "paper")}

        ref = point(nonlinear)
        J = {m: np.zeros((2, len(names))) for m in ref}
        for j, name in enumerate(names):
            sd = float(np.sqrt(max(S[j, j], 0.0)))
            if sd == 0:
                continue
            hi, lo = variant(name, step * sd), variant(name, -step * sd)
            if hi is None or lo is None:
                continue
            ph, pl = point(hi), point(lo)
            for m in J:
                if ph[m] is None or pl[m] is None:
                    continue
                d = ph[m] - pl[m]
                d[1] = np.angle(np.exp(1j * d[1]))
                J[m][:, j] = d / (2 * step * sd)
        for m, e in self.estimates_.items():
            if e and "gain" in e:
                e["cov_stage1"] = J[m] @ S @ J[m].T
                e["cov"] = e["cov_noise"] + e["cov_stage1"]
                e["jac_stage1"] = J[m]
        self._set_intervals()
        return self

    def _nls(self, hm, ks, c, var, rho, th_k, W=None, x0=None) -> dict:
        """Weighted NLS over the harmonics (ML under Gaussian noise); intervals from the Fisher matrix.

        With ``W`` (the distortion of w) the harmonic model is evaluated numerically."""
        sd = np.sqrt(var)
        if x0 is None:
            # coarse grid: cost(g, phi) = const + sum |D|^2/v - 2 Re(conj(c) D e^{-jk phi'}) / v
            g_grid = np.geomspace(1e-3, 1e2, 151)
            D = hm.D(rho * g_grid, ks)                                      # (G, K)
            phis = np.linspace(0, 2 * np.pi, 360, endpoint=False)
            E = np.exp(-1j * np.outer(phis, ks))                            # (F, K)
            grid = (np.abs(D) ** 2 / var).sum(1)[:, None] - 2 * ((np.conj(c) / var) * D) @ E.T
            i, j = np.unravel_index(np.argmin(grid.real), grid.shape)
            x0 = np.array([g_grid[i], phis[j] + th_k])
        x0 = np.asarray(x0, float)

        dist = DistortedHarmonics(hm, W, ks) if W is not None else None
        last: dict = {}

        def model(x):
            # MINPACK asks for the residuals and then the Jacobian at the same point: computed once
            key = (float(x[0]), float(x[1]))
            if last.get("key") != key:
                if dist is None:
                    e = np.exp(-1j * ks * (x[1] - th_k))
                    C = hm.D(rho * x[0], ks) * e
                    out = C, rho * hm.dD(rho * x[0], ks) * e, -1j * ks * C
                else:
                    C, dr, dp = dist(rho * x[0], x[1] - th_k)
                    out = C, rho * dr, dp
                last["key"], last["out"] = key, out
            return last["out"]

        def res(x):
            r = (c - model(x)[0]) / sd
            return np.concatenate([r.real, r.imag])

        def jac(x):
            _, dg, dp = model(x)
            dg, dp = -dg / sd, -dp / sd
            return np.column_stack([np.concatenate([dg.real, dg.imag]), np.concatenate([dp.real, dp.imag])])

        sol_x, sol_cost, _ = lm(res, jac, x0, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        g, phi = sol_x
        if g < 0:   # the odd part of h is invariant under (g, phi) -> (-g, phi + pi); report g > 0
            g, phi = -g, phi + np.pi
            sol_x, sol_cost, _ = lm(res, jac, np.array([g, phi]))
            g, phi = sol_x
        Jm = jac(np.array([g, phi]))
        try:
            cov = np.linalg.inv(Jm.T @ Jm)
        except np.linalg.LinAlgError:
            cov = np.full((2, 2), np.inf)
        return {"gain": float(g), "phase": float(phi), "cov": cov, "cost": float(sol_cost * 2),
                "dof": int(2 * ks.size - 2)}

    def _paper(self, hm, ks, c, var, rho, th_k, cost, sig) -> dict:
        """Eq. (37) generalised: one harmonic k; ambiguities resolved by the other harmonics."""
        k = self.harmonic if self.harmonic is not None else (max(sig) if sig else int(ks.max()))
        if k not in ks:
            raise HwidError(f"harmonic {k} is not predicted by h (degree {hm.degree}) or is above Nyquist; "
                            f"choose one of {ks.tolist()}")
        j = int(np.flatnonzero(ks == k)[0])
        ck, vk = c[j], var[j]
        P = hm.poly(k)
        unit = 1.0 if np.abs(P.real).sum() >= np.abs(P.imag).sum() else 1j
        Pr = (P / unit).real                                     # D_k(r) = unit * Pr(r)
        s = abs(ck)
        roots = []
        for sign in (1.0, -1.0):
            q = Pr.copy()
            q[0] -= sign * s
            q = np.trim_zeros(q, "b")
            if q.size < 2:
                continue
            rr = np.polynomial.polynomial.polyroots(q)
            roots += [float(r.real) for r in rr if abs(r.imag) < 1e-9 * max(1, abs(r)) and r.real > 0]
        if not roots:
            raise HwidError(f"harmonic {k}: |D_k(r)| = s_k has no positive root; h does not explain "
                            f"the measured amplitude {s:.3g}")
        best = None
        for r in roots:
            g = r / rho
            Dk = hm.D(r, [k])[0]
            Dg = hm.D(rho * g, ks)
            for m in range(k):
                phi = th_k + (np.angle(Dk) - np.angle(ck) + 2 * np.pi * m) / k
                cc = cost(g, phi, Dg)
                if best is None or cc < best[0]:
                    best = (cc, g, phi, r)
        _, g, phi, r = best
        dPr = np.polynomial.polynomial.polyval(r, np.polynomial.polynomial.polyder(Pr))
        var_g = vk / (rho * dPr) ** 2 if dPr != 0 else np.inf
        var_p = vk / (k ** 2 * s ** 2) if s > 0 else np.inf
        return {"gain": float(g), "phase": float(phi), "cov": np.diag([var_g, var_p]), "harmonic": int(k),
                "roots": [r_ / rho for r_ in roots]}


# -------------------------------------------------------------------------------------------- results

def _estimator(cfg) -> LinearEstimator:
    lc = cfg.identification.linear
    return LinearEstimator(method=lc.method, harmonic=lc.harmonic,
                           hold_correction=getattr(lc, "hold_correction", True),
                           noise_model=getattr(lc, "noise_model", "auto"))


def _per_frequency_dict(est: LinearEstimator) -> dict:
    hf = est.harmonics_.to_dict()
    hf["predicted_re"] = est.predicted_.real
    hf["predicted_im"] = est.predicted_.imag
    hf["used_harmonics"] = est.used_harmonics_.astype(float)
    hf["significant_harmonics"] = est.significant_harmonics_.astype(float)
    hf["input_correction"] = [est.input_correction_.real, est.input_correction_.imag]
    hf["input_distortion"] = est.input_distortion_
    hf["distortion_modelled"] = est.distortion_ is not None
    hf["w_amplitude"] = est.w_amplitude_
    ests = {}
    for name, e in est.estimates_.items():
        if e is None:
            continue
        ests[name] = {k: (np.asarray(v, float) if isinstance(v, (np.ndarray, list, tuple)) else v)
                      for k, v in e.items()}
    hf["estimates"] = ests
    return hf


def unwrap_phase(omega, phase) -> np.ndarray:
    """Unwrap ``phi`` across increasing frequency, starting from its principal value (``G(0) = 1``)."""
    omega = np.asarray(omega, float)
    phase = np.asarray(phase, float).copy()
    order = np.argsort(omega)
    prev = None
    for i in order:
        if prev is not None:
            phase[i] += 2 * np.pi * np.round((prev - phase[i]) / (2 * np.pi))
        prev = phase[i]
    return phase


def estimate_response(records, sines, nonlinear, cfg=None, estimator: LinearEstimator | None = None,
                      parametric: bool = True, precompensator: str = "auto", passes: int = 1) -> LinearResult:
    """Estimate ``G(j omega_i)`` from sine records already measured (one per ``sines[i]``).

    ``passes``: how many times the input's distortion is modelled through a rational G fitted to
    the previous pass (a pre-compensated input needs one; a bare sine through a backlash, whose
    harmonics are a third of its fundamental, needs G at frequencies above the band measured, and
    each pass refits it from better estimates)."""
    from hwid.identify.parametric import fit_rational
    est0 = estimator or (_estimator(cfg) if cfg is not None else LinearEstimator())
    lc = cfg.identification.linear if cfg is not None else None
    max_order, fit_delay = (lc.max_order, lc.fit_delay) if lc else (4, False)
    w = np.array([s.omega for s in sines], float)

    def one_pass():
        out = []
        for rec, s in zip(records, sines):
            e = LinearEstimator(**{k: getattr(est0, k) for k in ("method", "harmonic", "k_max", "confidence",
                                                                 "hold_correction", "noise_model",
                                                                 "propagate_stage1")})
            out.append(e.fit(rec, s, nonlinear))
        return out

    ests = one_pass()
    has_cov = getattr(nonlinear, "cov", None) is not None and np.size(getattr(nonlinear, "cov")) > 0
    if parametric and (has_cov or any(e.input_distortion_ > 0 for e in ests)):
        # second pass: (a) the pre-compensated input's harmonics reach w through G(j k omega) (a
        # Backlash-Inverse plant, or a perturbed stage 1); (b) the stage 1 uncertainty is propagated.
        # Both need G at the harmonics: taken from a first-pass parametric fit.
        def g_fit():
            try:
                ph = unwrap_phase(w, [e.phase_ for e in ests])
                g = np.array([e.gain_ for e in ests])
                return fit_rational(w, g * np.exp(-1j * ph), np.array([e.cov_ for e in ests]), gain=g, phase=ph,
                                    max_order=max_order, fit_delay=fit_delay).freqresp
            except HwidError:
                return None

        g_model = g_fit()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExtrapolationWarning)     # the first pass has warned already
            for k in range(max(1, int(passes))):
                if k > 0:
                    g_model = g_fit() or g_model
                for e in ests:
                    if g_model is not None and e.input_distortion_ > 0:
                        e.refit(nonlinear, g_model)
            for e in ests:
                if has_cov and getattr(est0, "propagate_stage1", True):
                    e.add_stage1_uncertainty(nonlinear, g_model)
    gain = np.array([e.gain_ for e in ests])
    phase_raw = np.array([e.phase_ for e in ests])
    phase = unwrap_phase(w, phase_raw)
    shift = phase - phase_raw
    gain_ci = np.array([e.gain_ci_ for e in ests])
    phase_ci = np.array([e.phase_ci_ for e in ests]) + shift[:, None]
    cov = np.array([e.cov_ for e in ests])
    harm = []
    for e, sh in zip(ests, shift):
        d = _per_frequency_dict(e)
        for x in d["estimates"].values():
            if "phase" in x:
                x["phase"] = x["phase"] + sh
                x["phase_ci"] = np.asarray(x["phase_ci"], float) + sh
        harm.append(d)
    warns = [m for e in ests for m in e.warnings_]
    par: dict = {}
    if parametric and len(sines) >= 1:
        try:
            fit = fit_rational(w, gain * np.exp(-1j * phase), cov, gain=gain, phase=phase,
                               max_order=max_order, fit_delay=fit_delay)
            par = fit.to_dict()
            warns += list(fit.warnings)
        except HwidError as err:
            warns.append(f"parametric fit: {err}")
            par = {"num": [], "den": [], "delay": 0.0, "error": str(err)}
    return LinearResult(w, float(sines[0].amplitude), gain, gain_ci, phase, phase_ci, cov, est0.method,
                        np.array([e.crlb_[0] for e in ests]), np.array([e.crlb_[1] for e in ests]), par,
                        tuple(harm), np.array([e.extrapolated_ for e in ests]), tuple(warns), precompensator)


def identify_linear(cfg, nonlinear, plant=None, journal_dir=None, progress: bool | None = None):
    """Stage 2 end to end: pre-compensated sines, ``G_hat(j omega_i)``, the parametric model.

    Parameters
    ----------
    cfg : hwid.config.Config
    nonlinear : NonlinearLike
        Stage 1 result (``load_nonlinear(path)`` or :class:`KnownNonlinear`).
    plant : optional
        A plant (``run(name, u, z=...)``); default ``make_plant(cfg, journal_dir=journal_dir)``.

    Returns
    -------
    (LinearResult, list of Record)
    """
    sines, records = run_sines(cfg, nonlinear, plant, journal_dir, progress)
    res = estimate_response(records, sines, nonlinear, cfg,
                            precompensator=cfg.identification.linear.precompensator)
    return res, records
