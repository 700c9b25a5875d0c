"""Scoring, ranking and the verdict of the diagnosis: each fitted effect as a :class:`Candidate`
with its explained fraction and its BIC score on the validation experiments (the scores are
defined in :mod:`hwid.diagnose.rank`'s docstring), candidates ranked, the floor measured down to
what the candidates leave, and the verdict.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from hwid.identify.rails import describe


@dataclass
class Candidate:
    effect: str
    block: str
    params: dict
    gap_fit: float
    gap_after: float
    explained_fraction: float
    score: float
    k: float
    per_experiment: dict = field(default_factory=dict)
    predictions: list = field(default_factory=list, repr=False)   # validation model outputs
    model: dict | None = None      # F and G re-estimated with the effect (identified models)
    at_bound: bool = False         # pressed against a bound that defines the effect
    theta: np.ndarray | None = field(default=None, repr=False)   # the fit's parameters (effect's, then F's and G's)
    fitted: object = field(default=None, repr=False)   # the Effect theta belongs to (a family at its chosen degree)
    stripped: bool = False     # fitted on the baseline with the identified G's outside modes taken out
    own_fitter: object = field(default=None, repr=False, compare=False)   # the fitter of that baseline, if so
    intervals: dict | None = None   # 95 % intervals of ``params`` (:mod:`hwid.diagnose.intervals`)
    stands_in: str | None = None    # why the fit is not the effect (:meth:`Effect.stands_in`): never the verdict

    def params_text(self) -> str:
        """The parameters with their 95 % intervals, ``undetermined`` where the fit cannot tell
        one (``coulomb 3.15 [1.66, 4.65], fed_back 0``)."""
        iv = self.intervals or {}
        parts = []
        for name, value in self.params.items():
            if name in iv and iv[name] is None:
                parts.append(f"{name} undetermined (fitted {value:.4g})")
            elif iv.get(name) is not None:
                parts.append(f"{name} {value:.4g} [{iv[name][0]:.4g}, {iv[name][1]:.4g}]")
            else:
                parts.append(f"{name} {value:.4g}")
        return ", ".join(parts)

    def to_dict(self) -> dict:
        d = {"effect": self.effect, "params": self.params, "gap_after": self.gap_after,
             "explained_fraction": self.explained_fraction, "score": self.score,
             "block": self.block, "gap_fit": self.gap_fit, "n_params": self.k,
             "per_experiment": self.per_experiment, "at_bound": self.at_bound}
        if self.model is not None:
            d["model"] = self.model
        if self.intervals is not None:
            d["intervals"] = self.intervals
        if self.stands_in is not None:
            d["stands_in"] = self.stands_in
        return d


def excess(gap_rms: float, sigma: float) -> float:
    """The gap above the noise floor, ``sqrt(max(gap^2 - sigma^2, 0))`` (noise adds in quadrature)."""
    return float(np.sqrt(max(gap_rms * gap_rms - sigma * sigma, 0.0)))


def bic_score(gap_before: float, gap_after: float, k: float, n_eff: float) -> float:
    """The candidate's BIC on the validation data, ``n_eff ln(gap_before^2 / gap_after^2) - k ln(n_eff)``
    (see the module docstring)."""
    return float(n_eff * np.log(max(gap_before ** 2, 1e-300) / max(gap_after ** 2, 1e-300)) - k * np.log(n_eff))


def explained_fraction(gap_before: float, gap_after: float, sigma: float) -> float:
    """``1 - excess(after) / excess(before)``, clipped to [0, 1]: the share of the gap above the
    noise floor that an effect removes."""
    eb = excess(gap_before, sigma)
    if eb <= 0:
        return 0.0
    return float(np.clip(1.0 - excess(gap_after, sigma) / eb, 0.0, 1.0))


def alternative_baseline(primary: list[Candidate], other: list[Candidate], gap_ref: float, sigma: float,
                         n_eff: float) -> list[Candidate]:
    """Each effect from whichever of two baselines fits the fit experiments better, measured against
    ``gap_ref`` (the better baseline alone: explained fraction and score recomputed), ranked.

    The two baselines of an identified model: its G refit as it is, and its G with the lightly
    damped modes outside the identified band taken out before the refit. Stage 2 may put a mode
    far above the band into G where the plant slews (its harmonics fall off faster than G's); the
    refit then damps that pair into a low-pass that stands in for the slew, and no effect is left to
    take its place (a 5.6 units/s rate limit on a Backlash-Inverse rig, 13 rad/s above a band up to
    2.5 rad/s, explained 0.41). Taken out before the refit, the same pair may be half of the
    plant's dynamics (curved borders distort the harmonics of a slow plant into a pair at 0.37 rad/s
    just above a band up to 0.2): which baseline an effect uses is decided by the fit data alone."""
    by = {c.effect: c for c in other}
    out = []
    for c in primary:
        o = by.get(c.effect)
        pick = o if (o is not None and np.isfinite(o.gap_fit) and o.gap_fit < c.gap_fit) else c
        out.append(dataclasses.replace(pick, explained_fraction=explained_fraction(gap_ref, pick.gap_after, sigma),
                                       score=bic_score(gap_ref, pick.gap_after, pick.k, n_eff)))
    return rank(out)


def rank(cands: list[Candidate], tie: float = 0.03, score_tie: float | None = None) -> list[Candidate]:
    """By explained fraction; candidates within ``tie`` of each other (or, with ``score_tie``, whose
    scores are within it of the top's) by score (fewer parameters win when they explain as much),
    after those whose fit pressed against a bound that defines them (a resonance at the largest
    damping a lightly damped mode may have explains as a plain low-pass would: a delay or a lag that
    explains as much is the better name)."""
    cands = sorted(cands, key=lambda c: -c.explained_fraction)
    out: list[Candidate] = []
    while cands:
        top = cands[0].explained_fraction
        grp = [c for c in cands if c.explained_fraction >= top - tie
               or (score_tie is not None and c.score >= cands[0].score - score_tie)]
        grp.sort(key=lambda c: (c.at_bound, -c.score))
        out += grp
        cands = [c for c in cands if c not in grp]
    return out


def refloor(cands: list[Candidate], gap_before: float, sigma: float,
            drift_plausible: bool) -> tuple[list[Candidate], float]:
    """The floor and the candidates with explained fractions measured down to ``min(sigma, smallest gap_after)``
    (eligible candidates; ``drift`` only when plausible), re-ranked. A model fitted on other data
    cannot remove the validation data's noise, so the smallest gap any candidate leaves is an upper
    bound on the noise; a floor from repeats above it carries more than noise."""
    gaps = [c.gap_after for c in cands if (c.effect != "drift" or drift_plausible) and np.isfinite(c.gap_after)]
    floor = min([sigma] + gaps)
    if floor >= sigma:
        return cands, sigma
    # measured down to the smallest gap left, the fractions stretch: candidates whose BIC scores are
    # within 10 of the top's (very strong evidence, Kass & Raftery 1995) are tied with it
    out = rank([dataclasses.replace(c, explained_fraction=explained_fraction(gap_before, c.gap_after, floor))
                for c in cands], score_tie=10.0)
    if not drift_plausible:     # listed last, as before
        out = [c for c in out if c.effect != "drift"] + [c for c in out if c.effect == "drift"]
    return out, floor


#: What an effect must remove to be named, both asked (:class:`Relevance`): ``(share, margin)``,
#: measured from the baseline the effect was fitted against (the model itself, or an identified
#: model's refit: what the refit removes by itself is no effect's).
#:
#: * ``share``: at least this fraction of the baseline's excess over the noise, in mean square
#:   (``gap_base^2 - gap_after^2 >= share (gap_base^2 - sigma^2)``): an effect that leaves nine
#:   tenths of what it is measured against has not found what makes the gap, however small the
#:   gap. It is a floor under the verdict's other routes (the test that finds what an effect leaves
#:   to be noise, the second test near the floor), which ask no share of an identified model.
#: * ``margin``: the RMS gap falls by at least this fraction of the noise floor. The floor from the
#:   repeats is itself known to about ``sqrt(kappa / 2n)``, 1.1-1.6 % over the 2000-4000 samples
#:   of a diagnosis's repeats: a smaller fall is within what the floor's own error allows, however
#:   large the likelihood ratio a long record gives it. A delay credited with a refit's shrink
#:   (issue 47: 73 % of a refit left 1 % above the floor) took 0.9 % of the floor off the gap; the
#:   right names held near the floor that the second test was built for took 2.6 % (a 0.36 s
#:   delay, identified: 1.036x -> 1.010x) to 9 % (a sensor clip, identified: 1.037x -> 0.944x).
RELEVANT = (0.1, 0.02)


@dataclass(frozen=True)
class Relevance:
    """Whether an effect removes a practically relevant part of the gap (:data:`RELEVANT`):
    ``gap_base`` is the RMS gap of the baseline every candidate was measured against (the model
    itself, or its refit), ``sigma`` the noise floor."""

    gap_base: float
    sigma: float

    def __call__(self, c: "Candidate") -> bool:
        share, margin = RELEVANT
        if not np.isfinite(c.gap_after):
            return False
        removed = self.gap_base ** 2 - c.gap_after ** 2
        return bool(removed >= share * max(self.gap_base ** 2 - self.sigma ** 2, 0.0)
                    and self.gap_base - c.gap_after >= margin * self.sigma)

    def describe(self, c: "Candidate") -> str:
        """Why ``c`` removes too little, in numbers."""
        removed = self.gap_base ** 2 - c.gap_after ** 2
        excess = max(self.gap_base ** 2 - self.sigma ** 2, 1e-300)
        return (f"{c.effect} takes the gap from {self.gap_base:.4g} (the baseline it was fitted against) to "
                f"{c.gap_after:.4g}: {removed / excess:.3g} of that baseline's mean-square excess over the floor "
                f"and {(self.gap_base - c.gap_after) / self.sigma:.3g} of the floor {self.sigma:.4g}; a named effect "
                f"removes at least {RELEVANT[0]:g} of the one and {RELEVANT[1]:g} of the other")


#: The most parameters an effect named for part of the excess may have (``partial`` in
#: :func:`eligible`). A one- or two-parameter effect (a clip, a slew, a dead zone, a lag) explains
#: a share only by being there; a family chosen in shape from the data (curved borders, 5-13
#: parameters; a drift's smoother) also takes up part of the identified model's own error and part
#: of any effect outside the catalogue: a saturation between G's two lags, identified, was called
#: curved borders for 0.44 of the excess at 1.22x the floor (judged seed 8837), and the friction
#: damper's log for 0.34 at 1.69x.
PARTIAL_MAX_PARAMS = 2


def eligible(c: Candidate, drift_plausible: bool, threshold: float = 0.5, leaves_noise=None,
             max_left: float | None = None, partial: tuple[float, float] | None = None,
             relevant: Relevance | None = None) -> bool:
    """Whether ``c`` could be the verdict: it pays for its parameters (a positive score), leaves at
    most ``max_left`` (an RMS gap; ``None``: no bound) and either explains at least ``threshold`` of
    the excess, or leaves a gap the gap test takes for noise (``leaves_noise(gap_after)``, the same
    test that found the gap; ``None``: not asked), or, with ``partial = (share, left)``, explains at
    least ``share`` and leaves at most ``left`` (an RMS gap); ``drift`` only when plausible.

    The second clause is for effects seen near the floor: where the gap is a fifth above the noise,
    what an identified model itself leaves (its identification error, a floor measured a few per cent
    low) can be as large as the effect's excess, and an effect that takes the gap down to where the
    test no longer tells it from noise has explained all that the records can show, whatever share
    of the excess that is. The third is the same for an identified model a little further from the
    floor (:data:`hwid.diagnose.conclude.ID_PARTIAL`), and only for an effect of at most
    :data:`PARTIAL_MAX_PARAMS` parameters.

    ``relevant`` (:class:`Relevance`; ``None``: not asked): whatever else, the effect removes a
    practically relevant part of the gap (:data:`RELEVANT`). A fit that stands in for something
    else (``c.stands_in``, read from its intervals) is never eligible."""
    if c.effect == "drift" and not drift_plausible:
        return False
    if c.stands_in is not None:
        return False
    if not c.score > 0:
        return False
    if relevant is not None and not relevant(c):
        return False
    if max_left is not None and not c.gap_after <= max_left:
        return False
    return bool(c.explained_fraction >= threshold
                or (leaves_noise is not None and np.isfinite(c.gap_after) and leaves_noise(c.gap_after))
                or (partial is not None and c.k <= PARTIAL_MAX_PARAMS and c.explained_fraction >= partial[0]
                    and c.gap_after <= partial[1]))


def verdict(cands: list[Candidate], significant: bool, drift_plausible: bool,
            threshold: float = 0.5, leaves_noise=None, max_left: float | None = None,
            partial: tuple[float, float] | None = None, relevant: Relevance | None = None) -> Candidate | None | str:
    """``"none"`` when the gap is noise; the first ranked candidate if it could be the verdict
    (:func:`eligible`: it explains at least ``threshold`` of the excess, or leaves only noise, pays
    for its parameters and leaves at most ``max_left``); else ``"unexplained"``.

    ``drift`` is only eligible when the plant does not repeat itself (``drift_plausible``): a
    deterministic effect gives the same residual on repeated runs, a drift does not."""
    if not significant:
        return "none"
    for c in cands:
        if c.effect == "drift" and not drift_plausible:
            continue
        return c if eligible(c, drift_plausible, threshold, leaves_noise, max_left, partial, relevant) else "unexplained"
    return "unexplained"


#: Two candidates are told apart when the paired test of their squared errors on the validation
#: data (:func:`paired_z`) exceeds this many standard deviations.
SEPARATE_Z = 3.0


def paired_z(a: Candidate, b: Candidate, y_val, m_val, sigma: float, kappa: float) -> float:
    """How many standard deviations apart the two candidates' mean-square errors on the validation
    data are: ``mean(e_a^2 - e_b^2)`` against its standard deviation under the hypothesis that both
    fit equally well, ``2 sigma rms(p_a - p_b) sqrt(kappa / n)`` (a Diebold-Mariano test with the
    noise's correlation time ``kappa``). Two candidates whose predictions differ by less than the
    noise can show over these records get a small ``z`` whatever their gaps."""
    z, _, _ = paired_stats([paired_sums(y, pa, pb, m, sigma, kappa)
                            for y, pa, pb, m in zip(y_val, a.predictions, b.predictions, m_val)], sigma)
    return abs(z)


def paired_sums(y, a, b, m, sigma: float, kappa: float) -> tuple[float, float, int, float]:
    """One record's terms of the paired test of predictions ``a`` and ``b`` of ``y`` over the scored
    samples ``m``: ``sum(e_a^2 - e_b^2)``, its variance when both fit alike
    (``4 sigma^2 sum (a - b)^2 kappa``), the scored samples and ``sum(e_b^2)``."""
    m = np.asarray(m, bool)
    y, a, b = (np.asarray(x, float)[m] for x in (y, a, b))
    ea, eb, d = y - a, y - b, a - b
    return float(ea @ ea - eb @ eb), 4.0 * sigma * sigma * float(d @ d) * max(kappa, 1.0), int(m.sum()), float(eb @ eb)


def paired_stats(sums, sigma: float) -> tuple[float, float, float]:
    """Records' :func:`paired_sums` together: the signed ``z`` (positive where ``a`` fits worse),
    ``mean(e_a^2 - e_b^2)`` and ``mean(e_b^2) - sigma^2``, both in units of ``sigma^2``."""
    num, var, n, base = (sum(s[i] for s in sums) for i in range(4))
    if n == 0:
        return 0.0, 0.0, 0.0
    power = n * sigma * sigma
    return (float(num / np.sqrt(var)) if var > 0 else 0.0), num / power, base / power - 1.0


def indistinguishable(cands: list[Candidate], y_val, m_val, sigma: float, kappa: float, drift_plausible: bool,
                      threshold: float = 0.5, leaves_noise=None, max_left: float | None = None,
                      partial: tuple[float, float] | None = None, relevant: Relevance | None = None) -> list[dict]:
    """Groups of catalogue effects that fit these records equally well within the noise.

    Among the candidates that could be a verdict (:func:`eligible`), in ranked order: each group is
    the best remaining one and every other whose squared errors on the validation data are not
    :data:`SEPARATE_Z` standard deviations apart from it (:func:`paired_z`). Only groups of two or
    more are returned, each as ``{"effects", "gap_after", "z"}`` (``z`` against the group's first)."""
    able = [c for c in cands if eligible(c, drift_plausible, threshold, leaves_noise, max_left, partial, relevant)
            and c.predictions]
    groups = []
    while able:
        head, rest = able[0], able[1:]
        zs = {c.effect: paired_z(head, c, y_val, m_val, sigma, kappa) for c in rest}
        members = [c for c in rest if zs[c.effect] < SEPARATE_Z]
        if members:
            groups.append({"effects": [head.effect] + [c.effect for c in members],
                           "gap_after": {c.effect: float(c.gap_after) for c in [head] + members},
                           "z": {c.effect: zs[c.effect] for c in members}})
        able = [c for c in rest if c not in members]
    return groups


def simplest_in_group(verdict, groups: list[dict], cands: list[Candidate]):
    """The verdict among the members of its group (:func:`indistinguishable`) with the fewest
    parameters (``k``; ties to the better ranked): where the validation data cannot tell two
    explanations apart, the one that assumes less is named and the others are listed beside it.
    A drift neither gives way nor is given way to (its ``k`` is the smoother's effective degrees
    of freedom, not a count of physical parameters). Other verdicts are returned unchanged.

    Seed 4513's third-order delay (0.20 s), identified, came out as a well-damped `resonance`
    (zeta 0.22 at 12.4 rad/s, two parameters) with `time_delay` (one) in its group: the mode's
    ringing is far above what the plant's G passes, and only the phase lag both give shows.

    A member is named instead only where it explains at least :data:`SIMPLER_SHARE` of what the
    verdict explains: near the floor the paired test cannot part candidates whose shares of the
    excess differ widely (judged seed 6379's resonance at 8.6 rad/s from a log explained 0.67, a
    delay 0.09, both at 1.00x the floor, and the delay had been named; seed 4513's delay explained
    0.31 against the resonance's 0.51)."""
    if not isinstance(verdict, Candidate) or verdict.effect == "drift":
        return verdict
    group = next((g["effects"] for g in groups if verdict.effect in g["effects"]), None)
    if not group:
        return verdict
    members = [c for c in cands if c.effect in group and c.effect != "drift"
               and (c is verdict or c.explained_fraction >= SIMPLER_SHARE * verdict.explained_fraction)]
    return min(members, key=lambda c: c.k) if members else verdict


#: the least share of the verdict's explained fraction a simpler member of its group must explain
#: to be named instead (:func:`simplest_in_group`)
SIMPLER_SHARE = 0.5


def named_from_rails(cands, on_rails, dt: float, echo):
    """``(sensor_saturation, why)`` where the gap test found nothing but the output rested on a
    sensor rail (:mod:`hwid.identify.rails`): the rig clipped where the validation experiments do not
    show it (a log whose clipped stretch lies in its opening, where the model's state is unknown),
    and a model without the sensor's range is missing it; None if that effect was not fitted."""
    named = next((c for c in cands if c.effect == "sensor_saturation"), None)
    if named is None:
        return None
    why = (f"{describe(on_rails, dt)}: the sensor clips and the model does not; sensor_saturation is named "
           "from the rails, as the validation experiments show no gap")
    echo(why)
    return named, why
