"""The baseline's surgery on an identified G, before and after the diagnosis refits it: what the
refit must not keep because an effect of the catalogue should explain it instead, or because the
sines could not place it.

* :func:`split_modes` - lightly damped pole pairs outside the sine band (left to ``resonance``);
* :func:`cancel_slow_pairs` - near-cancelling pole-zero pairs below the band (a gain step);
* :func:`mirror_rhp_zeros` - right-half-plane zeros, the excess phase a delay gives (left to
  ``time_delay``).
"""
from __future__ import annotations

import numpy as np

from hwid.diagnose.effects import ZETA_LIGHT


def split_modes(num, den, band, zeta_light: float):
    """G's lightly damped pole pairs (``zeta < zeta_light``) with ``omega_n`` outside ``band``,
    taken out: ``(num, den, modes, cancelled)`` with ``den`` (and, when a pair was cancelled,
    ``num``) normalised to 1 at ``s = 0``, ``modes`` the ``(omega_n, zeta)`` taken out, and
    ``cancelled`` whether a pair went with a complex zero pair within 20 % of its frequency (an
    artefact of the rational fit, not a mode: both leave G and the pair is not in ``modes``)."""
    lo, hi = float(min(band)), float(max(band))
    num = np.trim_zeros(np.asarray(num, float), "f")
    zeros = list(np.roots(num)) if num.size > 1 else []
    keep, modes, cancelled = [], [], False
    for r in np.roots(np.asarray(den, float)):
        if r.imag < -1e-12 * abs(r):
            continue
        wn = abs(r)
        if r.imag > 1e-12 * wn and wn > 0:
            z = -r.real / wn
            if z < zeta_light and not lo <= wn <= hi:
                near = [q for q in zeros if q.imag > 1e-12 * abs(q) and abs(abs(q) / wn - 1) < 0.2]
                if near:
                    q = min(near, key=lambda q: abs(abs(q) - wn))
                    zeros = [x for x in zeros if not (np.isclose(x, q) or np.isclose(x, np.conj(q)))]
                    cancelled = True
                else:
                    modes.append((float(wn), float(max(z, 1e-3))))
                continue
            keep += [r, np.conj(r)]
        else:
            keep.append(r)
    den_red = np.real(np.poly(keep)) if keep else np.array([1.0])
    den_red = den_red / den_red[-1]
    if cancelled:       # G(0) = 1 kept: the pair's static gain goes with it
        num = np.real(np.poly(zeros)) if zeros else np.array([1.0])
        num = num / num[-1]
    return num, den_red, modes, cancelled


def cancel_slow_pairs(num, den, band, ratio: float = 1.5):
    """G with the pole-zero pairs below ``band`` that nearly cancel taken out: ``(num, den, pairs)``,
    both normalised to 1 at ``s = 0``, ``pairs`` the ``(pole, zero)`` frequencies removed.

    A pole and a zero both below the lowest sine frequency, within ``ratio`` of each other, act on
    the band as a constant gain step (``|z/p|``) and a phase of a few degrees: the sines cannot
    place them, and with ``G(0) = 1`` they only make the static gain differ from the band's. That
    is an artefact of the rational fit to harmonics an effect has distorted (a clipping sensor on
    the paper's plant gave a pair at 0.0024 and 0.0026 rad/s under a band from 0.02), and in the
    time domain a creep over thousands of seconds that every experiment of the diagnosis shows;
    the re-estimated h carries whatever gain the pair stood for."""
    lo = float(min(band))
    num = np.trim_zeros(np.asarray(num, float), "f")
    den = np.trim_zeros(np.asarray(den, float), "f")
    if num.size < 2 or den.size < 2 or num[-1] == 0 or den[-1] == 0:
        return num, den, []
    zeros, poles = list(np.roots(num)), list(np.roots(den))
    pairs = []
    for z in sorted([q for q in zeros if abs(q.imag) <= 1e-12 * abs(q) and 0 < abs(q) < lo], key=abs):
        near = [p for p in poles if abs(p.imag) <= 1e-12 * abs(p) and 0 < abs(p) < lo
                and max(abs(p), abs(z)) < ratio * min(abs(p), abs(z))]
        if not near:
            continue
        p = min(near, key=lambda q: abs(np.log(abs(q) / abs(z))))
        zeros.remove(z)
        poles.remove(p)
        pairs.append((float(abs(p)), float(abs(z))))
    # below half the band, as many poles as zeros (complex ones too) whose gain step is within
    # ratio^2 act on the band as that step alone: stage 2 put two poles at 0.0073 and 0.0028 rad/s
    # and zeros at 0.0048 +- 0.0024j under a band from 0.02 (a saturation inside the paper's G), and
    # the validation designed from that G ran sines down to 0.003 rad/s, 34,551 rig-s
    low_z = [q for q in zeros if 0 < abs(q) < lo / 2]
    low_p = [q for q in poles if 0 < abs(q) < lo / 2]
    if low_z and len(low_z) == len(low_p):
        step = float(np.prod(np.abs(low_p)) / np.prod(np.abs(low_z)))
        if 1.0 / ratio ** 2 < step < ratio ** 2:
            for q in low_z:
                zeros.remove(q)
            for q in low_p:
                poles.remove(q)
            pairs += [(float(abs(p)), float(abs(z))) for p, z in zip(sorted(low_p, key=abs), sorted(low_z, key=abs))]
    if not pairs:
        return num, den, []
    num = np.real(np.poly(zeros)) if zeros else np.array([1.0])
    den = np.real(np.poly(poles)) if poles else np.array([1.0])
    return num / num[-1], den / den[-1], pairs


def mirror_rhp_zeros(num) -> tuple[np.ndarray, float]:
    """The numerator with its zeros in the right half plane mirrored to ``-conj(z)``, scaled so that
    its value at ``s = 0`` is kept (so ``|G(jw)|`` and ``G(0)`` are unchanged), and the group delay at
    ``w = 0`` that those zeros gave, ``sum 2 Re(z) / |z|^2`` (0 when there were none)."""
    num = np.trim_zeros(np.asarray(num, float), "f")
    if num.size < 2 or num[-1] == 0:
        return num, 0.0
    z = np.roots(num)
    rhp = z.real > 1e-9 * np.maximum(np.abs(z), 1.0)
    if not np.any(rhp):
        return num, 0.0
    hint = float(np.sum(2 * z[rhp].real / np.abs(z[rhp]) ** 2))
    new = np.real(np.poly(np.where(rhp, -np.conj(z), z)))
    return new * (num[-1] / new[-1]), hint


def has_outside_modes(G, band, zeta_light: float = ZETA_LIGHT) -> bool:
    """Whether G has a lightly damped pole pair outside ``band`` (see :func:`split_modes`)."""
    if band is None or len(G.den) < 3:
        return False
    _, _, modes, cancelled = split_modes(G.num, G.den, band, zeta_light)
    return bool(modes or cancelled)
