"""One ordinary lab session of a hidden rig (``generate.py --recorded``), logged to CSV like a lab
logs: not hwid's protocols.

The parts, in order, each one call of the rig: a staircase up and down, three plain sines, steps of
three sizes from the centre and back, a slow and a faster triangle, one long hold. Between parts the
logger pauses 5-20 s (the rig held at the last command meanwhile), so a reader splits the file there.

The classic session holds every level for the base's ``hold``. The wide session (``layout``) draws,
for some of the held parts (staircase, steps, long hold), every level's hold from 0.2 to 20 settling
times (log-uniform; settling time = 4 tau), and in some sessions cuts one part short, followed by a
longer gap (the logger stopped and was started again).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

import rigkit

#: the lab run's parts, in order; each is one call of the rig
LAB_PARTS = ["staircase", "sines", "steps", "triangles", "hold"]
#: the parts made of held levels (their holds may be drawn uneven)
HELD_PARTS = ("staircase", "steps", "hold")
#: the pause of the logger between parts (s): longer than 3 dt, so a reader splits the record there
LAB_PAUSE = (5.0, 20.0)
#: sample-time jitter of the logger, a fraction of dt (uniform, +-)
LAB_JITTER = 0.03
#: uneven holds: each level held this many settling times (log-uniform); settling time = 4 tau
UNEVEN_HOLDS = (0.2, 20.0)
#: share of wide sessions with one part cut short, the fraction of it kept, and the gap after it (s)
CUT_SHARE, CUT_KEEP, CUT_GAP = 0.35, (0.3, 0.8), (30.0, 120.0)
#: an effect shows in the lab log where it moves at least this many samples by more than the
#: noise's standard deviation (noise-free runs with and without it, the same rig otherwise)
LAB_VISIBLE_SAMPLES = 20


def lab_inputs(b: dict, holds: dict | None = None) -> list[np.ndarray]:
    """The lab run of a base plant (model units, one array per part). ``holds`` maps a held part to
    its per-level holds in seconds (default: the base's ``hold`` each, the long hold 3 of them)."""
    dt, hold = b["dt"], b["hold"]
    holds = holds or {}
    lo, hi = b["levels"]
    c, H = 0.5 * (lo + hi), 0.5 * (hi - lo)

    def held(levels, seconds):
        return np.repeat(np.round(np.asarray(levels, float), 4), np.round(np.asarray(seconds) / dt).astype(int))

    # (a) a staircase up and down over the levels range (the same 8 levels each way)
    grid = np.linspace(lo, hi, 8)
    stair_levels = np.concatenate([grid, grid[::-1][1:]])
    staircase = held(stair_levels, holds.get("staircase", hold))
    # (b) plain sines around the centre, 0.8 of the half range, 4 periods each, not pre-compensated
    sines = []
    for w in b["freqs"][1:4]:
        n = int(round(4 * 2 * np.pi / w / dt))
        sines.append(c + 0.8 * H * np.sin(w * dt * np.arange(n)))
    # (c) steps from the centre to +-0.25, +-0.5, +-0.9 of the half range and back
    steps = [c]
    for f in (0.25, 0.5, 0.9):
        for sgn in (1.0, -1.0):
            steps += [c + sgn * f * H, c]
    # (d) a slow and a faster triangle (peak to peak 0.95 of the range, two periods each; a whole
    # number of samples a quarter period, so a peak is one sample, not two equal ones)
    tris = []
    for period in (4 * hold, hold):
        quarter = int(round(period / dt / 4))
        k = np.arange(8 * quarter)
        tris.append(c + 0.95 * H * (1 - np.abs(((k + quarter) % (4 * quarter)) / quarter - 2.0)))
    # (e) one long hold
    return [staircase, np.concatenate(sines), held(steps, holds.get("steps", hold)), np.concatenate(tris),
            held([c + 0.4 * H], holds.get("hold", 3 * hold))]


def lab_layout(b: dict, rng: np.random.Generator) -> dict:
    """A wide session's layout: uneven holds for a non-empty random subset of the held parts, the
    pauses between parts, and (in ``CUT_SHARE`` of sessions) one part cut short with a gap after it."""
    settle = 4.0 * b["tau"]
    uneven = [p for p in HELD_PARTS if rng.random() < 0.5] or [str(rng.choice(HELD_PARTS))]
    n_levels = {"staircase": 15, "steps": 13, "hold": 1}
    holds = {}
    for part in uneven:
        s = settle * np.exp(rng.uniform(*np.log(UNEVEN_HOLDS), n_levels[part]))
        holds[part] = np.maximum(s, 20 * b["dt"]).round(3).tolist()
    inputs = lab_inputs(b, holds)
    pauses = rng.uniform(*LAB_PAUSE, len(inputs) - 1).tolist()
    cut = None
    if rng.random() < CUT_SHARE:
        k = int(rng.integers(len(inputs) - 1))          # a part with another after it
        keep = rng.uniform(*CUT_KEEP)
        inputs[k] = inputs[k][: max(int(keep * inputs[k].size), 20)]
        pauses[k] = float(rng.uniform(*CUT_GAP))
        cut = {"part": LAB_PARTS[k], "kept": round(float(keep), 3), "gap_s": round(pauses[k], 1)}
    return {"inputs": inputs, "pauses": pauses, "uneven": uneven, "cut": cut}


def _session(params: dict, b: dict, layout: dict | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The rig (a fresh state: a new session on the machine) through the session's parts; in a wide
    session it is held at the last command through every pause."""
    state: dict = {}
    dt = b["dt"]
    if layout is None:
        return [(u, rigkit.run(params, state, u, dt)) for u in lab_inputs(b)]
    parts = []
    for k, u in enumerate(layout["inputs"]):
        parts.append((u, rigkit.run(params, state, u, dt)))
        if k < len(layout["pauses"]):
            rigkit.pause(params, state, u[-1], layout["pauses"][k], dt)
    return parts


def lab_run(params: dict, b: dict, rng: np.random.Generator, layout: dict | None = None) -> dict:
    """The hidden rig through the lab run: the parts' inputs and outputs, the logger's timestamps,
    and the raw channels' scales. Without ``layout``: the classic session (pauses drawn here)."""
    dt = b["dt"]
    parts = _session(params, b, layout)
    t, t_next = [], 0.0
    for k, (u, _) in enumerate(parts):
        nominal = t_next + dt * np.arange(u.size)
        t.append(nominal + rng.uniform(-LAB_JITTER, LAB_JITTER, u.size) * dt)
        pause = rng.uniform(*LAB_PAUSE) if layout is None else (layout["pauses"] + [0.0])[k]
        t_next = nominal[-1] + dt + pause
    # raw = (value - offset) / scale: counts per model unit and a zero in counts, per channel
    chan = {}
    for name in ("input", "output"):
        counts = int(rng.integers(100, 2001))
        zero = int(rng.integers(-3000, 3001))
        scale = 1.0 / counts
        chan[name] = {"scale": scale, "offset": -zero * scale}
    start = np.datetime64("2019-01-01T00:00:00", "ms") + np.timedelta64(int(rng.integers(0, 4 * 365)), "D") \
        + np.timedelta64(int(rng.integers(7 * 3600, 17 * 3600)) * 1000 + int(rng.integers(0, 1000)), "ms")
    return {"parts": parts, "t": t, "channels": chan, "start": start,
            "temperature": (float(rng.uniform(19.0, 26.0)), int(rng.integers(2**31)))}


def lab_footprint(params: dict, b: dict, layout: dict | None = None) -> int:
    """How many samples of the lab run the rig's effect moves by more than the noise's standard
    deviation: the rig run noise-free through the lab run with its effect and without it (same
    between-call behaviour). A log the effect never touched cannot name it: for the recorded ways
    such a rig is a plain rig."""
    quiet = {**params, "noise": {**params["noise"], "std": 0.0}}
    runs = []
    for effect in (params["effect"], "none"):
        p = json.loads(json.dumps({**quiet, "effect": effect}))
        runs.append(np.concatenate([y for _, y in _session(p, b, layout)]))
    return int(np.sum(np.abs(runs[0] - runs[1]) > params["noise"]["std"]))


def write_lab(d: Path, cid: str, i: int, b: dict, run: dict) -> dict:
    """``lab.csv`` and ``recorded.yaml`` in the case directory; returns counts for the log line."""
    u = np.concatenate([p[0] for p in run["parts"]])
    y = np.concatenate([p[1] for p in run["parts"]])
    t = np.concatenate(run["t"])
    ci, co = run["channels"]["input"], run["channels"]["output"]
    raw_u = (u - ci["offset"]) / ci["scale"]
    raw_y = (y - co["offset"]) / co["scale"]
    stamps = run["start"] + np.round(t * 1000.0).astype(np.int64).astype("timedelta64[ms]")
    if np.any(np.diff(stamps) <= np.timedelta64(0, "ms")):
        raise RuntimeError(f"{cid}: lab timestamps do not increase")
    iso = np.datetime_as_string(stamps, unit="ms")
    t0, tseed = run["temperature"]
    trng = np.random.default_rng(tseed)
    temp = t0 + 0.3 * np.sin(2 * np.pi * t / 1800.0 + trng.uniform(0, 2 * np.pi)) + 0.02 * trng.standard_normal(t.size)
    # raw values to 1e-6 counts: the noise is at least 0.5 counts (0.005 units x 100 counts/unit),
    # so the rounding is below 1e-5 of its std
    with open(d / "lab.csv", "w", newline="") as fh:
        fh.write("timestamp,command,position,temperature\n")
        fh.writelines(f"{s},{a:.6f},{v:.6f},{c:.2f}\n" for s, a, v, c in zip(iso, raw_u, raw_y, temp))
    cfg = {"name": f"lab-{cid}", "seed": 7 + i, "sampling": {"dt": b["dt"]},
           "plant": {"kind": "recorded", "experiments": [
               {"file": "lab.csv", "time": {"column": "timestamp"},
                "input": {"column": "command", "scale": ci["scale"], "offset": ci["offset"]},
                "output": {"column": "position", "scale": co["scale"], "offset": co["offset"]},
                "role": "auto"}]}}
    (d / "recorded.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return {"rows": int(t.size), "parts": [int(p[0].size) for p in run["parts"]],
            "rig_seconds": float(sum(p[0].size for p in run["parts"]) * b["dt"])}
