"""The blind generator's base plants: four fixed ones (the classic draw) and three families whose
parameters are drawn per case (a two-mass drive, a slow thermal-like plant, a plant whose h folds).

A base is a dict: ``F`` (the gear: type, slopes, d^+ and d^-), ``G`` (num/den in descending powers of
s), ``h`` (ascending powers of w), ``noise`` (std, optional AR(1) coefficient), ``dt``, ``tau`` (G's
slowest time constant, s), ``omega_c`` (G's -3 dB bandwidth, rad/s), ``split`` (G cut into a slow and
a fast part, for a saturation between them), ``levels`` (the staircase range), ``hold`` (s per level),
``amp``, ``freqs`` (rad/s) and ``periods`` (the sine protocol): what a user writes in the config.
"""
from __future__ import annotations

import numpy as np

FIXED = {
    "paper": {
        "F": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.5, "d_minus": -0.5},
        "G": {"num": [0.2], "den": [1.0, 0.7, 0.1]}, "h": [0, 0.25, 0, -0.42, 0, 0.2],
        "noise": {"std": 0.01}, "dt": 0.05, "tau": 5.0, "omega_c": 0.177,
        "split": {"num1": [1.0], "den1": [2.0, 1.0], "num2": [2.0], "den2": [5.0, 1.0]},
        "levels": (-1.4, 1.2), "hold": 30.0, "amp": 1.0, "freqs": [0.02, 0.05, 0.1, 0.2], "periods": 3},
    "asymmetric": {
        "F": {"type": "backlash", "slope_up": 1.2, "slope_down": 0.8, "d_plus": 0.4, "d_minus": -0.2},
        "G": {"num": [4.0], "den": [1.0, 2.5, 4.0]}, "h": [0, 1.0, 0.25],
        "noise": {"std": 0.02, "ar": 0.5}, "dt": 0.02, "tau": 0.8, "omega_c": 1.9,
        "levels": (-1.5, 1.5), "hold": 5.0, "amp": 1.0, "freqs": [0.5, 1.0, 2.0, 4.0], "periods": 4},
    "inverse": {
        "F": {"type": "backlash_inverse", "slope_up": 1.0, "slope_down": 1.3, "d_plus": 0.2, "d_minus": -0.3},
        "G": {"num": [1.0], "den": [0.8, 1.0]}, "h": [0, 0.8, 0, -0.1],
        "noise": {"std": 0.005}, "dt": 0.02, "tau": 0.8, "omega_c": 1.25,
        "levels": (-1.2, 1.2), "hold": 5.0, "amp": 1.0, "freqs": [0.3, 0.6, 1.2, 2.5], "periods": 4},
    "third_order": {
        "F": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.3, "d_minus": -0.3},
        "G": {"num": [0.5, 3.0], "den": [1.0, 4.5, 6.5, 3.0]}, "h": [0, 1.0, 0, -0.2, 0, 0.02],
        "noise": {"std": 0.01}, "dt": 0.02, "tau": 1.0, "omega_c": 0.8,
        "split": {"num1": [1.0], "den1": [1.0, 1.0], "num2": [0.5, 3.0], "den2": [1.0, 3.5, 3.0]},
        "levels": (-1.5, 1.5), "hold": 6.0, "amp": 1.0, "freqs": [0.3, 0.6, 1.2, 2.4], "periods": 4},
}
#: bases drawn per case (``draw``)
DRAWN = ["two_mass", "thermal", "folded"]
CLASSIC = list(FIXED)
ALL = CLASSIC + DRAWN


def v_range(b: dict) -> tuple[float, float]:
    """The gear output's range over the staircase levels."""
    F = b["F"]
    lo, hi = b["levels"]
    if F["type"] == "backlash":
        return F["slope_down"] * (lo - F["d_minus"]), F["slope_up"] * (hi - F["d_plus"])
    return lo / F["slope_down"] + F["d_minus"], hi / F["slope_up"] + F["d_plus"]


def dc_gain(b: dict) -> float:
    return float(np.polyval(b["G"]["num"], 0) / np.polyval(b["G"]["den"], 0))


def w_range(b: dict) -> tuple[float, float]:
    """G's output range at rest over the staircase range."""
    a, c = sorted(g * dc_gain(b) for g in v_range(b))
    return float(a), float(c)


def y_range(b: dict) -> tuple[float, float]:
    v = np.linspace(*v_range(b), 200) * dc_gain(b)
    y = np.polyval(b["h"][::-1], v)
    return float(y.min()), float(y.max())


def h_slope(b: dict) -> float:
    """Mean |h'(w)| over G's output range: output units per w unit."""
    w = np.linspace(*w_range(b), 200)
    return float(np.mean(np.abs(np.polyval(np.polyder(np.asarray(b["h"][::-1], float)), w))))


def gain_at(b: dict, omega: float) -> float:
    """|G(j omega)|."""
    s = 1j * omega
    return float(abs(np.polyval(b["G"]["num"], s) / np.polyval(b["G"]["den"], s)))


def bandwidth(num, den) -> float:
    """The highest frequency at which |G| is still within -3 dB of its DC gain (past any peak)."""
    w = np.logspace(-4, 3, 4000)
    g = np.abs(np.polyval(num, 1j * w) / np.polyval(den, 1j * w)) / abs(np.polyval(num, 0) / np.polyval(den, 0))
    return float(w[np.nonzero(g >= 1 / np.sqrt(2))[0][-1]])


def _levels_inside_borders(F: dict, lo: float, hi: float) -> tuple[float, float]:
    """Shrink the staircase range so the two borders do not cross inside it (15 % margin)."""
    su, sd, dp, dm = F["slope_up"], F["slope_down"], F["d_plus"], F["d_minus"]
    if F["type"] == "backlash" and su != sd:
        cross = (su * dp - sd * dm) / (su - sd)
    elif F["type"] != "backlash" and su != sd:
        cross = (dm - dp) / (1 / su - 1 / sd)
    else:
        return lo, hi
    if cross > 0:
        hi = min(hi, 0.85 * cross)
    else:
        lo = max(lo, 0.85 * cross)
    return round(lo, 3), round(hi, 3)


def _finish(b: dict) -> dict:
    """Bandwidth, sampling-related protocol entries and the staircase range of a drawn base."""
    b["omega_c"] = round(bandwidth(b["G"]["num"], b["G"]["den"]), 4)
    b["levels"] = _levels_inside_borders(b["F"], *b["levels"])
    b["hold"] = float(round(b["hold"], 1))
    b["freqs"] = [float(round(f, 4)) for f in b["freqs"]]
    b["noise"] = {"std": b["noise"]["std"], **({"ar": round(b["noise"]["ar"], 3)} if b["noise"].get("ar") else {})}
    return b


def _r(x: float, k: int = 4) -> float:
    return float(round(x, k))


def draw(name: str, rng: np.random.Generator) -> dict:
    """The base ``name`` for one case: a fixed base as it is (no random numbers used), a drawn base
    with its parameters drawn from ``rng``."""
    if name in FIXED:
        return FIXED[name]
    U = rng.uniform
    if name == "two_mass":
        # a drive through a compliant shaft: a lightly damped mode inside the band behind a motor
        # lag; small asymmetric play (d^+ != -d^-, nearly parallel borders); h with an even term
        # (monotone over the range)
        wn, z, lag = _r(U(2.5, 3.5)), _r(U(0.1, 0.2)), _r(U(0.15, 0.5))
        su = _r(U(0.9, 1.1))
        F = {"type": "backlash", "slope_up": su, "slope_down": _r(su * U(0.97, 1.03)),
             "d_plus": _r(U(0.04, 0.1)), "d_minus": _r(-U(0.02, 0.06))}
        den = np.polymul([lag, 1.0], [1.0, 2 * z * wn, wn * wn]).tolist()
        tau = max(1 / (z * wn), lag)
        b = {"F": F, "G": {"num": [_r(wn * wn)], "den": [_r(c) for c in den]},
             "h": [0, 1.0, _r(U(0.1, 0.25)), _r(-U(0.0, 0.02))],
             "noise": {"std": 0.01, "ar": U(0.0, 0.5)}, "dt": 0.02, "tau": _r(tau),
             "split": {"num1": [1.0], "den1": [lag, 1.0], "num2": [_r(wn * wn)], "den2": [1.0, _r(2 * z * wn), _r(wn * wn)]},
             "levels": (-1.5, 1.5), "hold": 5 * tau, "amp": 1.0,
             "freqs": [0.4, 1.2, 0.7 * wn, 1.5 * wn], "periods": 4}
        return _finish(b)
    if name == "thermal":
        # a slow first-order plant (tau 6-10 s) behind a short lag; large play, unequal slopes
        T, T2, K = _r(U(6.0, 10.0), 3), _r(U(0.5, 1.5), 3), _r(U(0.8, 1.2))
        F = {"type": "backlash", "slope_up": _r(U(1.1, 1.4)), "slope_down": _r(U(0.7, 0.9)),
             "d_plus": _r(U(0.4, 0.7)), "d_minus": _r(-U(0.3, 0.6))}
        b = {"F": F, "G": {"num": [K], "den": [_r(T * T2), _r(T + T2), 1.0]},
             "h": [0, 1.0, _r(U(0.03, 0.12)), _r(-U(0.0, 0.02))],
             "noise": {"std": _r(U(0.01, 0.02)), "ar": U(0.0, 0.6)}, "dt": 0.1, "tau": T,
             "split": {"num1": [1.0], "den1": [T2, 1.0], "num2": [K], "den2": [T, 1.0]},
             "levels": (-2.2, 2.2), "hold": 5 * T, "amp": 1.2,
             "freqs": [0.2 / T, 0.5 / T, 1.0 / T, 2.5 / T], "periods": 3}
        return _finish(b)
    if name == "folded":
        # h non-invertible: its square term dominates over the lower part of the range, so h folds
        # back at a point a fifth to two fifths of the way up G's output range
        T1, T2, K = _r(U(0.3, 0.8), 3), _r(U(0.05, 0.2), 3), _r(U(0.8, 1.5))
        d = U(0.15, 0.35)
        F = {"type": str(rng.choice(["backlash", "backlash_inverse"])), "slope_up": _r(U(0.9, 1.1)),
             "slope_down": _r(U(0.9, 1.1)), "d_plus": _r(d), "d_minus": _r(-d * U(0.7, 1.3))}
        b = {"F": F, "G": {"num": [K], "den": [_r(T1 * T2), _r(T1 + T2), 1.0]}, "h": [0, 1.0, 1.0],
             "noise": {"std": 0.01}, "dt": 0.02, "tau": T1,
             "split": {"num1": [1.0], "den1": [T2, 1.0], "num2": [K], "den2": [T1, 1.0]},
             "levels": (-1.2, 1.2), "hold": 6 * T1, "amp": 1.0,
             "freqs": [0.3 / T1, 0.8 / T1, 1.6 / T1, 3.2 / T1], "periods": 4}
        b = _finish(b)
        wlo, whi = w_range(b)
        fold = wlo + U(0.2, 0.4) * (whi - wlo)
        a2 = 1.0 / max(whi - wlo, 1e-9)          # output span of order one
        b["h"] = [0, _r(-2 * a2 * fold), _r(a2), _r(U(-0.05, 0.05) * a2)]
        return b
    raise ValueError(f"unknown base {name!r}")
