"""A fast mode or a delay: told apart where the validation data can, said to be indistinguishable
where they cannot.

A lightly damped mode above the band G was identified on and a pure delay both turn the phase of
what passes G, and on experiments that barely reach the mode they fit alike. When the verdict is one
of the two and the other also removes a practically relevant part of the gap
(:class:`hwid.diagnose.verdict.Relevance`), both fitted and neither pressed against the bound that
defines it (a "mode" at the damping bound is a low-pass that stands in for a lag), the two are compared on the validation data
by the paired test of the diagnosis (:func:`hwid.diagnose.verdict.paired_z`: the difference of their
squared errors against its spread when both fit alike):

* below :data:`hwid.diagnose.verdict.SEPARATE_Z` their gaps after are within each other's
  uncertainty: the verdict keeps its name with the other in ``indistinguishable_from``, and the
  experiment that separates them is a sine near the fitted mode
  (:func:`hwid.diagnose.next_experiment.propose_mode_sine`);
* at or above it the data separate them and the one that fits better is named (where it is the
  other, it replaces the verdict if it pays for its parameters and does not stand in for something
  else).

Never the wrong one alone: either the data chose, or both are listed.
"""
from __future__ import annotations

from dataclasses import dataclass

from hwid.diagnose.verdict import SEPARATE_Z, Candidate, Relevance, paired_z

#: the two effects compared
PAIR = ("time_delay", "resonance")


@dataclass(frozen=True)
class Comparison:
    """The two candidates' gaps after, the paired ``z`` between them and the outcome: ``separable``
    (the data tell them apart) and ``better`` (the effect with the smaller gap after)."""

    gap_after: dict
    z: float
    separable: bool
    better: str

    def to_dict(self) -> dict:
        return {"effects": list(self.gap_after), "gap_after": dict(self.gap_after), "z": float(self.z),
                "bound": SEPARATE_Z, "separable": bool(self.separable), "better": self.better}


def compare(verdict, cands, relevant: Relevance, y_val, m_val, sigma: float, kappa: float) -> Comparison | None:
    """The comparison of a ``time_delay`` or ``resonance`` verdict with the other of the two, where
    both remove a relevant part of the gap (``relevant``) and both have predictions; None otherwise."""
    if not isinstance(verdict, Candidate) or verdict.effect not in PAIR:
        return None
    name = PAIR[1 - PAIR.index(verdict.effect)]
    other = next((c for c in cands if c.effect == name), None)
    if other is None or not (verdict.predictions and other.predictions) or other.stands_in is not None:
        return None
    if verdict.at_bound or other.at_bound:      # a "mode" at the damping bound is a low-pass, no mode
        return None
    if not (relevant(verdict) and relevant(other)):
        return None
    z = paired_z(verdict, other, y_val, m_val, sigma, kappa)
    better = min((verdict, other), key=lambda c: c.gap_after).effect
    return Comparison({verdict.effect: float(verdict.gap_after), name: float(other.gap_after)}, float(z),
                      bool(z >= SEPARATE_Z), better)


def settle(verdict, groups: list[dict], cands, comparison: Comparison | None, echo=None) -> tuple[object, list]:
    """``(verdict, groups)`` after ``comparison`` (module docstring): the groups with the two in
    one where the data cannot separate them; the better named where they can."""
    if comparison is None:
        return verdict, groups
    a, b = list(comparison.gap_after)
    if not comparison.separable:
        groups = [dict(g) for g in groups]
        group = next((g for g in groups if a in g["effects"] or b in g["effects"]), None)
        if group is None:
            groups.insert(0, {"effects": [a, b], "gap_after": dict(comparison.gap_after), "z": {b: comparison.z}})
        else:
            for e in (a, b):
                if e not in group["effects"]:
                    group["effects"] = list(group["effects"]) + [e]
                    group["gap_after"] = {**group.get("gap_after", {}), e: comparison.gap_after[e]}
                    group["z"] = {**group.get("z", {}), e: comparison.z}
        if echo is not None:
            echo(f"{a} and {b} leave {comparison.gap_after[a]:.4g} and {comparison.gap_after[b]:.4g} (paired z "
                 f"{comparison.z:.2g} < {SEPARATE_Z:g}): the validation data cannot tell the mode from the delay")
        return verdict, groups
    if comparison.better != verdict.effect:
        other = next(c for c in cands if c.effect == comparison.better)
        if other.score > 0 and not other.at_bound:
            if echo is not None:
                echo(f"{other.effect} fits the validation data better than {verdict.effect} (gap "
                     f"{other.gap_after:.4g} against {verdict.gap_after:.4g}, paired z {comparison.z:.2g}): "
                     f"{other.effect} is named")
            return other, [g for g in groups if verdict.effect not in g["effects"] or other.effect in g["effects"]]
    return verdict, groups
