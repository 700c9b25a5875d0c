"""F and G re-estimated with h (:class:`hwid.diagnose.rank.EffectFitter` with ``refit_g``): the
identified model's F and G as parameters of the diagnosis's baseline and of every effect's joint
fit, and the baseline's surgery on G (:mod:`hwid.diagnose.baseline`): lightly damped modes outside
the sine band, near-cancelling slow pairs, right-half-plane zeros and a pure delay are taken out of
the refit G and left to the catalogue's effects.

G's parameters are log factors on the free coefficients of the identified ``num/den`` (normalised
so ``G(0) = 1``), F's are shifts of ``d^+`` and ``d^-`` and a log factor on ``S^d``; each lies in a
box around the identified model (:meth:`GRefit._g_bounds`), moved to the refit for a model that
misses its own records (:meth:`GRefit._recentre`).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from hwid.diagnose import effects as effect_models
from hwid.diagnose.baseline import cancel_slow_pairs, mirror_rhp_zeros, split_modes
from hwid.diagnose.gap import rms
from hwid.diagnose.intervals import ON_BOX
from hwid.diagnose.modelsim import ReblockedSim
from hwid.model import InputNonlinearity


class GRefit:
    """The F-and-G half of :class:`hwid.diagnose.rank.EffectFitter` (its attributes: ``scale``,
    ``sf``, ``sfw``, ``svw``, ``sigma``, ``yv``, ``mv``, ``JOINT_TOL``, the residual ``_residual``
    with the unit-box maps, and h's refit ``_refit_predict``)."""

    G_FACTOR = 5.0
    RECENTRE_MOVES = 3      # moves of the refit's box for a model that misses its own records
    ZETA_LIGHT = effect_models.ZETA_LIGHT       # a pole pair of G below this damping ratio is a lightly damped mode

    def _init_g(self, F, G) -> None:
        self._f0 = F
        W = self.scale.u_width
        # F: both borders shifted by up to 10 % of the input range, S^d by a factor in [2/3, 3/2]
        # (the ascending slope is the normalisation, eq. 4a)
        self._f_free = [("d_plus", 0.1 * W), ("d_minus", 0.1 * W), ("slope_down", np.log(1.5))]
        self._g_free = []
        num = np.asarray(G.num, float)
        den = np.asarray(G.den, float)
        self._g_delay = float(G.delay)
        if den.size >= 2 and den[-1] != 0 and num[-1] != 0:
            self._g_num, self._g_den = num / den[-1], den / den[-1]
            self._g_num = self._g_num / self._g_num[-1]              # G(0) = 1
            self._g_free = [("num", k) for k in range(self._g_num.size - 1) if self._g_num[k] != 0] + \
                           [("den", k) for k in range(self._g_den.size - 1) if self._g_den[k] != 0]
        else:       # a static G, or one with a pole or zero at s = 0: kept as it is
            self._g_num, self._g_den = num, den
        self.refit_g = True
        self.g_p = np.zeros(self.n_g)
        self._g_cache = {}


    @property
    def n_g(self) -> int:
        """The model's re-estimated parameters (F's, then G's)."""
        return len(self._f_free) + len(self._g_free) if self.refit_g else 0

    def input_nl(self, m) -> InputNonlinearity:
        """F for the model parameters ``m`` (shifts of d+ and d-, log factor on S^d)."""
        F = self._f0
        a, b, c = (float(x) for x in np.asarray(m, float)[:3])
        dp, dm = F.d_plus + a, F.d_minus + b
        if dp <= dm:
            dp = dm = 0.5 * (dp + dm)
            dp += 1e-9
        return InputNonlinearity(F.type, F.slope_up, F.slope_down * np.exp(c), dp, dm)

    def linear(self, m):
        """G for the model parameters ``m`` (log factors on the free coefficients of num/den)."""
        from hwid.blocks.linear import LinearBlock
        num, den = self._g_num.copy(), self._g_den.copy()
        for (which, k), p in zip(self._g_free, np.asarray(m, float)[len(self._f_free):]):
            (num if which == "num" else den)[k] *= np.exp(p)
        return LinearBlock(tuple(num.tolist()), tuple(den.tolist()), self._g_delay)

    def _stable(self, G) -> bool:
        if len(G.den) <= 3:
            return True     # positive coefficients (the factors keep their signs): stable up to order 2
        return bool(np.all(np.real(np.roots(G.den)) < 0))

    def _g_sims(self, m):
        key = tuple(np.round(np.asarray(m, float), 12).tolist())
        hit = self._g_cache.get(key)
        if hit is None:
            if len(self._g_cache) > 8:
                self._g_cache.clear()
            F, G = self.input_nl(m), self.linear(m)
            hit = (ReblockedSim(self.sfw, F, G), ReblockedSim(self.svw, F, G))
            self._g_cache[key] = hit
        return hit

    def _split(self, eff, theta):
        """``theta`` -> (the effect's parameters, G's): G's are the last ``n_g``; without them, the
        baseline's G."""
        if eff is None:
            return None, (self.g_p if theta is None else np.asarray(theta, float))
        t = np.asarray(theta, float)
        ne = len(eff.params)
        return t[:ne], (t[ne:] if t.size > ne else self.g_p)

    def _g_bounds(self, eff=None):
        """F's and G's bounds; G's factor ``eff.g_factor`` where the effect sets one (an effect
        acting inside G's loop reshapes what stage 2 identified: :mod:`hwid.diagnose.effects_after_gear`)."""
        f = getattr(eff, "g_factor", None) or self.G_FACTOR
        b = np.r_[[w for _, w in self._f_free], np.full(len(self._g_free), np.log(f))]
        return -b, b

    def _fit_baseline_g(self) -> np.ndarray:
        """G's parameters with h re-estimated and no effect, from the identified G."""
        lo, hi = self._g_bounds()
        logs = (False,) * self.n_g

        def fun(x):
            return self._residual(None, self._from_unit(x, lo, hi, logs))
        x0 = self._to_unit(np.zeros(self.n_g), lo, hi, logs)
        try:
            sol = least_squares(fun, x0, bounds=(0.0, 1.0), diff_step=1e-3, max_nfev=20 * (self.n_g + 1),
                                method="trf", **self.JOINT_TOL)
        except ValueError:
            return np.zeros(self.n_g)
        r0 = fun(x0)
        return self._from_unit(sol.x, lo, hi, logs) if 2 * sol.cost < float(r0 @ r0) else np.zeros(self.n_g)

    def _recentre(self, min_ratio: float) -> None:
        """Where the baseline's refit ends on the edge of its box (a factor :attr:`G_FACTOR` on G's
        coefficients, F's shifts), the box moves to the refit model and the baseline is refitted from
        there, up to :attr:`RECENTRE_MOVES` times. Only for a model that misses its own records: its
        F and G are not a model of the plant to stay near. The moved box is kept only where its
        refit predicts the validation records within ``min_ratio`` (mean square) of the floor: a
        model of the same structure then fits the plant as it is now, and the model handed over was
        not that model (:func:`hwid.diagnose.model_check.changed_or_inadequate` says so). A model
        fitted across a change of the plant's gain put a slow zero into G to follow both halves; the
        refit in the first box stopped on its edge at 1.18x the floor, and the lag credited with the
        rest was the box, not the plant. Elsewhere the box stays where it was: a model that misses
        its records because an effect was left out of it (a slew the whole fit took out) would
        otherwise be bent towards that effect, and the effect's starts from the identified model
        left outside the box."""
        first = self._state()
        moved = False
        for _ in range(self.RECENTRE_MOVES):
            lo, hi = self._g_bounds()
            span = np.maximum(hi - lo, 1e-12)
            on_edge = (np.abs(self.g_p - lo) < ON_BOX * span) | (np.abs(hi - self.g_p) < ON_BOX * span)
            if not np.any(on_edge):
                break
            before = (self._refit_gap_fit(), self._state())
            self._init_g(self.input_nl(self.g_p), self.linear(self.g_p))
            self.g_p = self._fit_baseline_g()
            if not self._refit_gap_fit() < before[0]:
                self._restore(before[1])
                break
            moved = True
        if moved and not self._refit_gap_val() ** 2 <= min_ratio * self.sigma ** 2:
            self._restore(first)

    def _state(self) -> tuple:
        """What :meth:`_init_g` and a baseline refit set, for :meth:`_restore`."""
        return self._f0, self._g_num, self._g_den, self._g_free, self.g_p

    def _restore(self, state) -> None:
        self._f0, self._g_num, self._g_den, self._g_free, self.g_p = state
        self._g_cache = {}

    def _refit_gap_val(self) -> float:
        """The baseline's RMS gap on the validation records (h re-estimated)."""
        x = self._refit_predict(None, None, "val")
        return rms(np.concatenate([(y - xi)[m] for y, xi, m in zip(self.yv, x, self.mv)]))

    def _refit_gap_fit(self) -> float:
        """The baseline's residual on the fit records (h re-estimated), for :meth:`_recentre`."""
        r = self._residual(None, self.g_p)
        return float(r @ r)

    def _strip_modes(self, band, refit: bool = True) -> None:
        """Take lightly damped modes outside the identified band out of the refit G (``refit``), or
        out of the identified G before the baseline is refit (``refit=False``: the refit may damp
        such a pair into a plain low-pass that stands in for a slew or a lag, and then no effect
        is left to take its place).

        A resonance of the plant is inside the paper's structure (G is any linear system): stage 2
        may already have put a lightly damped pair into G from the harmonics, or the refit puts one
        there, and then no effect is left to explain. The catalogue's ``resonance`` is exactly such
        a mode outside the band the sines identified (``band = (omega_min, omega_max)``), so when
        the refit G has a complex pair with ``zeta < ZETA_LIGHT`` and ``omega_n`` outside the band,
        the baseline becomes that G without the pair (unit static gain, so ``G(0)`` is kept), F and
        G refit from there, and the pair is a starting point of the ``resonance`` effect, which
        must then earn it back on the validation data like any other effect."""
        if band is None:
            return
        lo, hi = float(min(band)), float(max(band))
        F, G = self.input_nl(self.g_p), self.linear(self.g_p)
        den = np.asarray(G.den, float)
        if den.size < 3:
            return
        num, den_red, modes, cancelled = split_modes(G.num, den, (lo, hi), self.ZETA_LIGHT)
        if not modes and not cancelled:
            return
        if num.size > den_red.size:      # the pair cannot go without making G improper
            return
        self.modes = self.modes + modes
        self._replace_g(F, num, den_red, G.delay, refit)

    def _replace_g(self, F, num, den, delay, refit: bool = True) -> None:
        """The model's G becomes ``num/den`` (F kept), re-estimated from there when ``refit``."""
        from hwid.blocks.linear import LinearBlock
        self._init_g(F, LinearBlock(tuple(np.asarray(num, float).tolist()), tuple(np.asarray(den, float).tolist()),
                                    delay))
        if refit:
            self.g_p = self._fit_baseline_g()

    def _cancel_slow_pairs(self, band, refit: bool = True) -> None:
        """Take the near-cancelling pole-zero pairs below the band (:func:`cancel_slow_pairs`) out
        of G: of the identified G before the baseline is refit (``refit=False``), and of the refit
        G, which can move a pair of the identified G below the band (a pair at 0.0127 and 0.0131
        rad/s under a band from 0.02 on a paper-base rig; without it, that G's other poles were the
        plant's own), refit from there."""
        if band is None:
            return
        F, G = self.input_nl(self.g_p), self.linear(self.g_p)
        num, den, pairs = cancel_slow_pairs(G.num, G.den, band)
        if not pairs:
            return
        self.cancelled_pairs = self.cancelled_pairs + pairs
        self._replace_g(F, num, den, G.delay, refit)

    def _strip_rhp_zeros(self) -> None:
        """Mirror zeros of the refit G in the right half plane into the left one.

        A transport delay is inside the paper's structure as well (G(jw) is any frequency response),
        and a rational G fitted to the harmonics takes it as excess phase: a zero ``z`` with
        ``Re z > 0`` (``(1 - s/z) / (1 + s/z)`` is the first Pade approximant of ``exp(-2 s / z)``);
        the refit keeps its coefficients' signs, so no effect is left to explain it (a delay of 0.15 s
        on a second-order plant was called ``none`` on four blind rigs). The catalogue's
        ``time_delay`` is that excess phase, so each such zero is mirrored to ``-conj(z)`` (``|G(jw)|``
        and ``G(0)`` unchanged, the excess phase gone), F and G are refit from there, and the group
        delay the zeros gave, ``sum 2 Re(z) / |z|^2``, is a starting point of ``time_delay``, which
        must then earn it back on the validation data like any other effect."""
        F, G = self.input_nl(self.g_p), self.linear(self.g_p)
        new, hint = mirror_rhp_zeros(G.num)
        if hint <= 0:
            return
        self._replace_g(F, new, G.den, G.delay)
        self.delay_hint = hint

    def _strip_delay(self) -> None:
        """Take an identified G's pure delay out of the refit G (:meth:`_strip_rhp_zeros` says why
        for excess phase; a delay fitted explicitly, as the whole fit from logs does, is the same
        excess phase by name). The refit G is then re-estimated without it, and the delay is a
        starting point of ``time_delay``, which must earn it back on the validation data. A
        delay the refit G's poles can stand in for leaves no gap, and no effect is named. The delay
        taken out is ``delay_block``: a block of the model, as the whole fit's slew and clip are,
        not a feature of its rational G (:func:`hwid.diagnose.conclude.gap_test_step`)."""
        if self._g_delay <= 0.1 * self.sf.dt:     # a tenth of a sample is no delay
            return
        F, G = self.input_nl(self.g_p), self.linear(self.g_p)
        self._replace_g(F, G.num, G.den, 0.0)
        self.delay_hint += float(G.delay)
        self.delay_block = float(G.delay)
