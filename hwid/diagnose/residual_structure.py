"""What an unexplained remainder looks like: tests on the residual ``r = y - y_model``.

Each test regresses the residual on one kind of signal the model lacks and asks whether the
coefficients are zero. The residual is autocorrelated (coloured noise, and the model's error passes
through G), so each regression is prewhitened by the residual's own AR filter (feasible GLS):

* ``direction_of_motion`` - on the signs of the input's and the model output's last moves (held
  while they rest): a remainder that depends on which way the plant last went (hysteresis,
  friction, at the actuator or at the output shaft);
* ``varying_gain`` - on the model output times the session time, with the model output itself as a
  control: a remainder that scales with the output and changes over the course of the tests;
* ``loop`` - on past model outputs, the present one as a control: the remainder follows the output's
  history beyond the model (the output feeds back, or the dynamics differ). Past *measured*
  outputs would carry the noise's own correlation, which is not a loop;
* ``harmonics`` - on sines and cosines at the harmonics of a sine experiment's fundamental: a
  periodic remainder the model lacks.

:func:`residual_structure` takes them in forward steps, each for what it explains beyond those
already found, and returns the significant ones (Bonferroni over the tests run) as
``{"kind", "evidence", "p_value"}``, most significant first, or one ``{"kind": "none", ...}`` item.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: family-wise level of the tests together
ALPHA = 0.01
#: harmonics of the fundamental tested on sine experiments
HARMONICS = 5


@dataclass(frozen=True)
class Segment:
    """One experiment's stretch to test: input, measured and model output, sample time, the
    samples that count (``mask``), and the fundamental (rad/s) of a sine experiment."""

    u: np.ndarray
    y: np.ndarray
    y_model: np.ndarray
    dt: float
    mask: np.ndarray | None = None
    omega: float | None = None

    @property
    def keep(self) -> np.ndarray:
        return np.ones(self.u.size, bool) if self.mask is None else np.asarray(self.mask, bool)


def _whitening(e, order: int) -> np.ndarray:
    """The AR(``order``) prediction-error filter ``[1, -a_1, ..., -a_p]`` of ``e`` (least squares)."""
    n = e.size
    if n <= 4 * order:
        return np.array([1.0])
    E = np.column_stack([e[order - k - 1:n - k - 1] for k in range(order)])
    a, *_ = np.linalg.lstsq(E, e[order:], rcond=None)
    return np.concatenate([[1.0], -a])


def gls_wald(r, X, controls=None, ar_order: int = 8) -> tuple[float, int]:
    """Wald statistic that the coefficients of ``X`` are zero in ``r ~ 1 + controls + X``;
    chi-square with ``X.shape[1]`` degrees of freedom under the null (:func:`gls_wald_groups`)."""
    return gls_wald_groups(r, {"x": X}, controls, ar_order)["x"]


def gls_wald_groups(r, groups: dict, controls=None, ar_order: int = 8) -> dict:
    """For each group of columns, the Wald statistic that its coefficients are zero in the joint
    regression ``r ~ 1 + controls + all groups``, and its degrees of freedom: what each group
    explains beyond the others.

    The residual's own correlation is taken out first (feasible GLS: an AR(``ar_order``) filter
    fitted to the least-squares residual is applied to both sides), then the classical covariance
    of the whitened regression applies."""
    r = np.asarray(r, float)
    cols = {k: np.atleast_2d(np.asarray(X, float).T).T for k, X in groups.items()}
    parts = [np.ones((r.size, 1))] + ([np.atleast_2d(np.asarray(controls, float).T).T] if controls is not None else [])
    first = sum(p.shape[1] for p in parts)
    A = np.hstack(parts + list(cols.values()))
    spread = A.std(axis=0)
    A = A / np.where(spread > 0, spread, 1.0)       # columns on one scale: the tests are unchanged, their numerics better
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    filt = _whitening(r - A @ coef, ar_order)
    p = filt.size - 1
    r_w = np.convolve(r, filt)[p:r.size]
    A_w = np.column_stack([np.convolve(col, filt)[p:r.size] for col in A.T])
    coef, *_ = np.linalg.lstsq(A_w, r_w, rcond=None)
    e = r_w - A_w @ coef
    s2 = float(e @ e) / max(e.size - A_w.shape[1], 1)
    cov = s2 * np.linalg.pinv(A_w.T @ A_w)
    out, at = {}, first
    for k, X in cols.items():
        idx = slice(at, at + X.shape[1])
        b = coef[idx]
        out[k] = (float(b @ np.linalg.pinv(cov[idx, idx]) @ b), X.shape[1])
        at += X.shape[1]
    return out


def last_direction(u, tol: float = 0.0) -> np.ndarray:
    """+1 where the signal last moved up, -1 where it last moved down (moves of ``tol`` or less
    ignored), the first move's sign before it."""
    du = np.diff(np.asarray(u, float), prepend=u[0])
    step = np.where(np.abs(du) > tol, np.sign(du), 0.0)
    idx = np.where(step != 0, np.arange(step.size), 0)
    np.maximum.accumulate(idx, out=idx)
    out = step[idx]
    out[idx == 0] = step[0]
    return out


def _lagged(x, k: int) -> np.ndarray:
    return np.concatenate([np.full(k, x[0]), x[:-k]]) if k else x


def _direction(segs, r) -> tuple[np.ndarray, str] | None:
    """The direction of the input's last move and of the model output's (a play or friction at the
    actuator follows the first, one at the output shaft the second; G's lag tells them apart)."""
    cols = {"input": np.concatenate([last_direction(s.u)[s.keep] for s in segs]),
            "model output": np.concatenate([last_direction(s.y_model, 1e-9 * (np.ptp(s.y_model) or 1.0))[s.keep]
                                            for s in segs])}
    cols = {k: v for k, v in cols.items() if not np.all(v == v[0])}
    if not cols:
        return None
    parts = [f"after a rising {name} it differs from that after a falling one by "
             f"{float(np.mean(r[d > 0]) - np.mean(r[d < 0])):.3g}"
             for name, d in cols.items() if np.any(d > 0) and np.any(d < 0)]
    return np.column_stack(list(cols.values())), "the residual depends on the direction of motion: " + "; ".join(parts)


def _varying_gain(segs, r) -> tuple[np.ndarray, str] | None:
    """The model output times the session time (the output itself is a control)."""
    x = np.concatenate([s.y_model[s.keep] for s in segs])
    if r.size < 20 or np.ptp(x) == 0:
        return None
    t = np.linspace(-1.0, 1.0, r.size)      # session time, in the order the experiments ran
    return ((x - x.mean()) * t,
            "the residual scales with the model output by a factor that changes over the session")


def _loop(segs, r, lags=(2, 8, 32)) -> tuple[np.ndarray, str] | None:
    """Past model outputs (the present one is a control)."""
    if r.size < 20 * len(lags):
        return None
    past = np.vstack([np.column_stack([_lagged(s.y_model, k)[s.keep] for k in lags]) for s in segs])
    return past, (f"the residual depends on past outputs (lags {list(lags)} samples) beyond the model: "
                  f"the output feeds back, or the dynamics differ from the model's")


def _harmonics(segs, r) -> tuple[np.ndarray, str] | None:
    """Sines and cosines at harmonics 1-5 of each sine experiment's fundamental, zero elsewhere."""
    sizes = [int(np.sum(s.keep)) for s in segs]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    blocks, found = [], []
    for i, s in enumerate(segs):
        ks = [k for k in range(1, HARMONICS + 1) if s.omega and k * s.omega < np.pi / s.dt]
        if not ks or sizes[i] < 4 * len(ks) + 10:
            continue
        t = np.arange(s.u.size)[s.keep] * s.dt
        X = np.zeros((r.size, 2 * len(ks)))
        X[offsets[i]:offsets[i + 1]] = np.column_stack([f(k * s.omega * t) for k in ks for f in (np.sin, np.cos)])
        blocks.append(X)
        found.append(f"{s.omega:g} rad/s")
    if not blocks:
        return None
    return np.hstack(blocks), f"the residual is periodic at harmonics 1-{HARMONICS} of the sine experiments ({', '.join(found)})"


def residual_structure(segments, alpha: float = ALPHA) -> list[dict]:
    """The significant structures of the residual (module docstring), most significant first; one
    ``{"kind": "none", ...}`` item when no test rejects at the family-wise level ``alpha``.

    The kinds are taken in forward steps: the one that explains most of the residual first, then
    each further one only for what it explains beyond those already found (a joint regression,
    :func:`gls_wald_groups`), so a large misfit of one kind does not make every other kind
    significant through what they share (a stick-slip's square wave is also periodic). The
    p-value of an item is that of its step."""
    from scipy import stats     # here: scipy.stats costs half a second at start-up
    segs = [s for s in segments if s.u.size and np.any(s.keep)]
    if not segs:
        return [{"kind": "none", "evidence": "no residual to test", "p_value": 1.0}]
    r = np.concatenate([(s.y - s.y_model)[s.keep] for s in segs])
    x = np.concatenate([s.y_model[s.keep] for s in segs])
    columns = {"direction_of_motion": _direction, "varying_gain": _varying_gain, "loop": _loop,
               "harmonics": _harmonics}
    built = {kind: f(segs, r) for kind, f in columns.items()}
    built = {kind: b for kind, b in built.items() if b is not None}
    if not built:
        return [{"kind": "none", "evidence": "the residual is too short to test", "p_value": 1.0}]
    level = alpha / len(built)
    found, remaining = [], list(built)
    while remaining:
        # the kind that explains most beyond those already found (log p: p itself underflows)
        trials = []
        for kind in remaining:
            groups = {k: built[k][0] for k in [f["kind"] for f in found] + [kind]}
            stat, q = gls_wald_groups(r, groups, controls=x)[kind]
            trials.append((float(stats.chi2.logsf(stat, q)), kind))
        log_p, kind = min(trials)
        if log_p >= np.log(level):
            break
        found.append({"kind": kind, "evidence": built[kind][1], "p_value": float(np.exp(log_p))})
        remaining.remove(kind)
    if found:
        return found
    # nothing found: the loop stopped at its first step, where each kind was tested alone
    return [{"kind": "none", "evidence": f"no test of {', '.join(built)} rejects at the family-wise level {alpha:g}",
             "p_value": float(np.exp(log_p))}]
