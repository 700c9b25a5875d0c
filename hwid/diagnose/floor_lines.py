"""What the noise floor set aside, and how it bears on the verdict.

Repeats of one input differ by noise alone on a plant that repeats itself: whatever the plant does
deterministically cancels in their difference; a settled hold's scatter is noise alone too. A
narrow-band component of either (:func:`hwid.spectral_lines.find_lines`, ``NoiseFloor.lines``) is
a disturbance at a frequency of its own (a periodic load, a pick-up) that meets each repeat at
another phase; a slow excess (``NoiseFloor.slow_z``) is a wander. Neither is noise, so neither is in the floor; both are
reported in ``residual_structure`` (:func:`structure_items`).

The one catalogue effect that can leave a line in the repeats' differences is a lightly damped
mode still ringing from the state each repeat started in: a ``resonance`` verdict whose ``omega_n``
lies within :data:`MODE_TOLERANCE` of every line keeps its name. Any other verdict, ``none``
included, becomes ``unexplained`` (:func:`verdict_with_lines`): no effect of the chain makes a
line at a frequency of its own.
"""
from __future__ import annotations

import numpy as np

#: a line within this relative distance of a fitted resonance's ``omega_n`` is that mode ringing
MODE_TOLERANCE = 0.1
#: the slow excess of the repeats' differences (z-score) above which a wander is reported: the
#: level at which the diagnosis lets a drift be named (:func:`hwid.diagnose.conclude.drift_step`)
WANDER_Z = 10.0


def structure_items(floor) -> list[dict]:
    """``residual_structure`` items for what ``floor`` (:class:`hwid.diagnose.gap.NoiseFloor`) set
    aside: one ``narrow_band`` item per line (``frequency_hz``, ``rad_s``, ``amplitude``,
    ``p_value``, ``variance_share``) and a ``wander`` item where the repeats differ slowly."""
    out = []
    for ln in getattr(floor, "lines", ()):
        d = ln.to_dict()
        out.append({**d, "evidence": (f"what the noise floor is estimated from (the repeats' differences, or the "
                                      f"settled holds' scatter) holds a sinusoid at {d['rad_s']:.4g} rad/s "
                                      f"({d['frequency_hz']:.4g} Hz), amplitude {d['amplitude']:.3g} there, "
                                      f"{100 * d['variance_share']:.0f} % of its variance: a disturbance at a "
                                      "frequency of its own, not noise; set aside from the noise floor")})
    if floor.slow_z > WANDER_Z:
        out.append({"kind": "wander", "rms": float(floor.slow_rms), "z": float(floor.slow_z),
                    "p_value": float(np.exp(-0.5 * floor.slow_z ** 2)),
                    "evidence": (f"the repeated experiments differ slowly (RMS {floor.slow_rms:.3g} of their "
                                 f"differences' block means, z = {floor.slow_z:.3g}): a wander, not noise; "
                                 "left out of the noise floor")})
    return out


def with_floor_items(items: list[dict], floor) -> list[dict]:
    """``items`` (the residual's tests) preceded by the floor's (:func:`structure_items`); a
    ``none`` item is dropped where the floor set something aside."""
    extra = structure_items(floor)
    if not extra:
        return list(items)
    return extra + [it for it in items if it.get("kind") != "none"]


def verdict_with_lines(verdict, why: str, floor, echo=None) -> tuple[object, str]:
    """``(verdict, why)``: ``unexplained`` where the floor set a line aside that the verdict does
    not account for (module docstring); as given otherwise."""
    lines = list(getattr(floor, "lines", ()))
    if not lines or verdict == "unexplained":
        return verdict, why
    effect = getattr(verdict, "effect", verdict)
    if effect == "resonance":
        wn = float(verdict.params.get("omega_n", np.nan))
        if all(abs(ln.omega / wn - 1.0) <= MODE_TOLERANCE for ln in lines):
            return verdict, why
    at = ", ".join(f"{ln.omega:.4g} rad/s" for ln in lines)
    why = (f"what the noise floor is estimated from (the repeats' differences, or the settled holds' scatter) "
           f"holds a narrow-band component at {at}, set aside from the floor: a disturbance at a frequency of "
           f"its own, which no catalogue effect makes"
           + (f"; {effect} does not account for it" if effect != "none" else "") + ": unexplained")
    if echo is not None:
        echo(why)
    return "unexplained", why
