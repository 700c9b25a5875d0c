"""A lab's log of a simulated rig, written as a CSV with jittered ISO timestamps in raw units, for
the recorded-plant diagnosis tests: a staircase up and down, plain sines, steps of several sizes,
triangles and a long hold, each part a separate run (the logger paused between them).

The rig is hwid's own chain (:meth:`hwid.model.HWModel.simulate`) with an optional input-side
effect applied to the command first; its parameters are the tests' truth."""
from __future__ import annotations

import numpy as np
import pandas as pd
import yaml

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.blocks.slew import slewed
from hwid.model import HWModel, InputNonlinearity

DT = 0.02
SIGMA = 0.02
F = {"type": "backlash", "slope_up": 1.2, "slope_down": 0.8, "d_plus": 0.4, "d_minus": -0.2}
G = {"num": [4.0], "den": [1.0, 2.5, 4.0]}
H = [0.0, 1.0, 0.25]
MODEL = {"plant": {"kind": "hammerstein_wiener", "input_nonlinearity": F, "linear": G,
                   "output_nonlinearity": {"polynomial": H}, "noise": {"std": SIGMA}}}


def lab_parts(hold: float = 4.0, lo: float = -1.5, hi: float = 1.5) -> list[np.ndarray]:
    """The lab run's inputs, one array per part."""
    def held(levels):
        return np.repeat(np.asarray(levels, float), int(round(hold / DT)))

    def sine(omega, periods=4):
        t = np.arange(int(periods * 2 * np.pi / omega / DT)) * DT
        return 1.2 * np.sin(omega * t)

    def triangle(period, n):
        s = (np.arange(int(n * period / DT)) * DT / period) % 1.0
        return 1.4 * (2 * np.abs(2 * s - 1) - 1)

    return [held(np.r_[np.linspace(lo, hi, 8), np.linspace(hi, lo, 8)]),
            np.concatenate([sine(w) for w in (0.7, 1.4, 2.8)]),
            held([0, 0.4, 0, -0.4, 0, 0.8, 0, -0.8, 0, 1.4, 0, -1.4, 0]),
            np.concatenate([triangle(5 * hold, 2), triangle(1.5 * hold, 3)]),
            held([0.7, 0.7, 0.7])]


def write_lab(tmp_path, name: str = "lab", rate: float | None = None, seed: int = 0, parts=None,
              one_record: bool = False, ar: float = 0.0, carry: bool = False, linear: dict | None = None,
              drift: tuple[float, float] | None = None, opening_rail: tuple[float, float] | None = None,
              clip_between: tuple[float, float, float] | None = None, input_nonlinearity: dict | None = None):
    """Write ``NAME.csv`` and its recorded config ``NAME.yaml``; return the config path. ``ar``:
    the noise's lag-1 coefficient (AR(1) noise of s.d. :data:`SIGMA`; 0 is white). ``carry``: the
    rate-limited actuator runs on through the pauses (each part starts where the last left it),
    else it starts at each part's first input. ``linear``: G's ``num, den`` (and ``delay``, s) in place of :data:`G`.
    ``drift``: ``(time_s, std)`` of an additive Ornstein-Uhlenbeck offset in y that runs on through
    the whole session (drawn after the noise, from its own generator). ``opening_rail``: ``(y, s)``,
    the first part's first ``s`` seconds read exactly ``y`` (a sensor at its rail while the rig came
    into its range as the log began). ``clip_between``: ``(tau1, tau2, level)``, G is the two lags
    ``1/(tau1 s + 1)`` then ``1/(tau2 s + 1)`` with a clip at +-``level`` between them (no
    catalogue effect; :func:`two_lags` is G for the model). ``input_nonlinearity``: F's ``type,
    slope_up, slope_down, d_plus, d_minus`` in place of :data:`F`."""
    rng = np.random.default_rng(seed)
    g = G if linear is None else linear
    f = F if input_nonlinearity is None else input_nonlinearity
    m = HWModel(InputNonlinearity(f["type"], f["slope_up"], f["slope_down"], f["d_plus"], f["d_minus"]),
                LinearBlock(tuple(g["num"]), tuple(g["den"]), float(g.get("delay", 0.0))), PolynomialH(tuple(H)))
    parts = lab_parts() if parts is None else parts
    if one_record:
        parts = [np.concatenate(parts)]
    session = slewed(np.concatenate(parts), rate, DT) if rate is not None and carry else None
    ends = np.cumsum([u.size for u in parts])
    if drift is not None:
        tau, std = drift
        a = np.exp(-DT / tau)
        kick = np.random.default_rng(seed + 1000).standard_normal(int(ends[-1])) * std * np.sqrt(1 - a * a)
        offset = np.zeros(int(ends[-1]))
        for j in range(1, offset.size):
            offset[j] = a * offset[j - 1] + kick[j]
    frames, t0 = [], 0.0
    for k, u in enumerate(parts):
        if session is not None:
            ue = session[ends[k] - u.size:ends[k]]
        else:
            ue = u if rate is None else slewed(u, rate, DT)
        e = rng.standard_normal(u.size)        # white: the same draws as before AR was an option
        if ar:
            e[1:] *= np.sqrt(1 - ar * ar)
            for k in range(1, u.size):
                e[k] += ar * e[k - 1]
        if clip_between is None:
            y = m.simulate(ue, DT).x + SIGMA * e
        else:
            v = m.simulate(ue, DT).v
            y = np.polyval(H[::-1], _lags_with_clip(v, *clip_between)) + SIGMA * e
        if drift is not None:
            y = y + offset[ends[k] - u.size:ends[k]]
        if opening_rail is not None and k == 0:
            y[:int(round(opening_rail[1] / DT))] = opening_rail[0]
        ts = t0 + (np.arange(u.size) + rng.uniform(-0.03, 0.03, u.size)) * DT
        frames.append(pd.DataFrame({"timestamp": pd.Timestamp("2026-03-02T10:00:00") + pd.to_timedelta(ts, "s"),
                                    "command": u * 100 + 2048, "position": y * 500, "temperature": 31.0}))
        t0 = ts[-1] + 10.0
    pd.concat(frames).to_csv(tmp_path / f"{name}.csv", index=False)
    cfg = {"name": name, "seed": 1, "sampling": {"dt": DT},
           "plant": {"kind": "recorded", "experiments": [
               {"file": f"{name}.csv", "time": {"column": "timestamp"},
                "input": {"column": "command", "scale": 0.01, "offset": -20.48},
                "output": {"column": "position", "scale": 0.002, "offset": 0.0}}]}}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def two_lags(tau1: float, tau2: float) -> dict:
    """G of two first-order lags in series (unit static gain)."""
    return {"num": [1.0], "den": [tau1 * tau2, tau1 + tau2, 1.0]}


def _lags_with_clip(v, tau1: float, tau2: float, level: float) -> np.ndarray:
    """``v`` through ``1/(tau1 s + 1)``, a clip at +-``level``, then ``1/(tau2 s + 1)`` (exact
    discretisation of each lag for a held input), both starting at rest at ``v[0]``."""
    a1, a2 = np.exp(-DT / tau1), np.exp(-DT / tau2)
    x1 = float(v[0])
    x2 = float(np.clip(x1, -level, level))
    out = np.empty_like(v)
    for i, vi in enumerate(v):
        out[i] = x2
        x2 = a2 * x2 + (1 - a2) * min(max(x1, -level), level)
        x1 = a1 * x1 + (1 - a1) * vi
    return out


def write_model(tmp_path, linear: dict | None = None):
    """The rig's own simulator without its effect (``linear``: G in place of :data:`G`)."""
    model = MODEL if linear is None else {"plant": {**MODEL["plant"], "linear": linear}}
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(model, sort_keys=False))
    return path


def write_log_csv(tmp_path, u, y, dt: float, whole_enabled: bool = True):
    """``u`` and ``y`` written as ``log.csv`` (columns cmd, pos) with a plain recorded config
    ``log.yaml`` beside it (a Backlash, G of order 1, h up to degree 3); the config's path."""
    (tmp_path / "log.csv").write_text("cmd,pos\n" + "\n".join(f"{a:.9g},{b:.9g}" for a, b in zip(u, y)))
    d = {"name": "log", "sampling": {"dt": dt},
         "plant": {"kind": "recorded", "experiments": [{"file": "log.csv", "input": {"column": "cmd"},
                                                        "output": {"column": "pos"}}]},
         "identification": {"nonlinear": {"input_type": "backlash"},
                            "whole": {"enabled": whole_enabled, "max_order": 1, "max_degree": 3,
                                      "input_type": "backlash"}}}
    (tmp_path / "log.yaml").write_text(yaml.safe_dump(d))
    return tmp_path / "log.yaml"
