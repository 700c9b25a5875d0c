"""Generator of hidden rigs for the blind check of ``hwid diagnose`` (issue 6).

Each case is a directory with

* ``rig_<id>.py`` -- an external-plant driver ``rig(u, dt) -> y`` (``plant.kind: external``) built on
  :mod:`rigkit` (numpy/scipy only, written apart from hwid): one of four base plants plus none, one
  catalogue effect at a random strength, or an effect outside the catalogue;
* ``config.yaml`` -- the config a user would write for that rig (identification protocols);
* ``model.yaml`` -- the rig's own simulator without the effect (the sim side for ``--model``).

With ``--recorded`` each case also gets

* ``lab.csv`` -- one ordinary lab run of the hidden rig, logged like a lab logs (not hwid's own
  protocols): a staircase up and down, three plain sines, steps of three sizes from the centre, a
  slow and a faster triangle, one long hold; each part one call of the rig (its between-call
  behaviour at every part's start), the logger paused 5-20 s between parts. Columns ``timestamp``
  (ISO 8601, ms, jittered by +-3 % of dt), ``command`` and ``position`` in raw units (counts, a
  per-case scale and offset), ``temperature`` (a distractor);
* ``recorded.yaml`` -- the recorded-plant config a lab user would write for that file.

The labels go to ``sealed.json`` beside the cases, which the runner opens only after every
diagnosis is done. Usage: ``python generate.py OUTDIR [--cases 40] [--seed 2024] [--recorded]``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))
import rigkit  # noqa: E402

CATALOGUE = ["input_saturation", "rate_limit", "input_deadzone", "curved_borders", "time_delay",
             "resonance", "sensor_lag", "sensor_saturation", "drift"]
OUTSIDE = ["hysteretic_friction", "gain_drift", "second_nonlinearity"]
# what a rig does between calls (rigkit's module docstring)
BETWEEN_CALLS = ["carry", "parked", "anywhere"]

# base plants: F, G (descending powers), h (ascending), noise, sampling and identification protocols
BASES = {
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


def _v_range(b):
    F = b["F"]
    lo, hi = b["levels"]
    if F["type"] == "backlash":
        return F["slope_down"] * (lo - F["d_minus"]), F["slope_up"] * (hi - F["d_plus"])
    return lo / F["slope_down"] + F["d_minus"], hi / F["slope_up"] + F["d_plus"]


def _y_range(b):
    g0 = np.polyval(b["G"]["num"], 0) / np.polyval(b["G"]["den"], 0)
    v = np.linspace(*_v_range(b), 200) * g0
    y = np.polyval(b["h"][::-1], v)
    return float(y.min()), float(y.max())


#: the shapes a bent border takes (rigkit._bow): symmetric and odd bends, S-curves, one-sided
#: stiffening, a local bump -- any smooth shape, not one family's own
BOW_SHAPES = ["sine", "parabola", "cubic", "s_curve", "one_sided", "bump"]


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def effect_params(effect: str, b: dict, rng: np.random.Generator) -> dict:
    """A random strength, clearly above the base plant's noise."""
    lo, hi = b["levels"]
    W, c = hi - lo, 0.5 * (lo + hi)
    T, wc = b["tau"], b["omega_c"]
    U = rng.uniform
    if effect == "input_saturation":
        return {"lo": c - 0.5 * W * U(0.6, 0.95), "hi": c + 0.5 * W * U(0.6, 0.85)}
    if effect == "rate_limit":
        # crossing the range in a fraction of a second (or a fraction of G's time constant, where
        # that is slower still: a faster slew is invisible behind G) up to a minute
        return {"rate": W / _log_uniform(rng, max(0.15 * T, 4 * b["dt"]), 60.0)}
    if effect == "input_deadzone":
        return {"delta": 0.5 * W * U(0.08, 0.2)}
    if effect == "curved_borders":
        sgn = rng.choice([-1.0, 1.0], 2)
        return {"shape": str(rng.choice(BOW_SHAPES)), "range": [lo, hi],
                "up": float(sgn[0] * U(0.03, 0.09)), "down": float(sgn[1] * U(0.03, 0.09))}
    if effect == "time_delay":
        return {"delay": T * U(0.08, 0.4)}
    if effect == "resonance":
        # anywhere above the band, up to a third of the Nyquist frequency
        return {"omega_n": min(wc * _log_uniform(rng, 1.5, 15.0), np.pi / b["dt"] / 3), "zeta": U(0.02, 0.15)}
    if effect == "sensor_lag":
        # up to the plant's own slowest time constant
        return {"tau": T * _log_uniform(rng, 0.2, 1.0)}
    if effect == "sensor_saturation":
        ylo, yhi = _y_range(b)
        m = max(abs(ylo), abs(yhi)) * U(0.65, 0.85)
        # an ADC reads its end codes exactly; a clipping amplifier before a noisy converter does not
        return {"lo": -m, "hi": m, "rail": str(rng.choice(["exact", "noisy"]))}
    if effect == "drift":
        return {"time_s": U(60, 300), "std": b["noise"]["std"] * U(4, 8)}
    if effect == "hysteretic_friction":
        ylo, yhi = _y_range(b)
        return {"width": (yhi - ylo) * U(0.03, 0.06)}
    if effect == "gain_drift":
        return {"amp": U(0.1, 0.2), "period": U(600, 1500), "phase": U(0, 2 * np.pi)}
    if effect == "second_nonlinearity":
        vlo, vhi = _v_range(b)
        return {**b["split"], "level": max(abs(vlo), abs(vhi)) * U(0.5, 0.7)}
    if effect == "none":
        return {}
    raise ValueError(effect)


# ------------------------------------------------------------------------------ the lab run (--recorded)

#: the lab run's parts, in order; each is one call of the rig
LAB_PARTS = ["staircase", "sines", "steps", "triangles", "hold"]
#: the pause of the logger between parts (s): longer than 3 dt, so a reader splits the record there
LAB_PAUSE = (5.0, 20.0)
#: sample-time jitter of the logger, a fraction of dt (uniform, +-)
LAB_JITTER = 0.03


def lab_inputs(b: dict) -> list[np.ndarray]:
    """The fixed lab run of a base plant (model units, one array per part): the log a lab already
    has, not hwid's protocols."""
    dt, hold = b["dt"], b["hold"]
    lo, hi = b["levels"]
    c, H = 0.5 * (lo + hi), 0.5 * (hi - lo)

    def held(levels, seconds):
        return np.repeat(np.round(np.asarray(levels, float), 4), int(round(seconds / dt)))

    # (a) a staircase up and down over the levels range (the same 8 levels each way)
    grid = np.linspace(lo, hi, 8)
    staircase = held(np.concatenate([grid, grid[::-1][1:]]), hold)
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
    return [staircase, np.concatenate(sines), held(steps, hold), np.concatenate(tris),
            held([c + 0.4 * H], 3 * hold)]


def lab_run(params: dict, b: dict, rng: np.random.Generator) -> dict:
    """The hidden rig through the lab run (a fresh state: a new session on the machine): the
    parts' inputs and outputs, the logger's timestamps, and the raw channels' scales."""
    state: dict = {}
    dt = b["dt"]
    parts = [(u, rigkit.run(params, state, u, dt)) for u in lab_inputs(b)]
    t, t_next = [], 0.0
    for u, _ in parts:
        nominal = t_next + dt * np.arange(u.size)
        t.append(nominal + rng.uniform(-LAB_JITTER, LAB_JITTER, u.size) * dt)
        t_next = nominal[-1] + dt + rng.uniform(*LAB_PAUSE)
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


#: an effect shows in the lab log where it moves at least this many samples by more than the
#: noise's standard deviation (noise-free runs with and without it, the same rig otherwise)
LAB_VISIBLE_SAMPLES = 20


def lab_footprint(params: dict, b: dict) -> int:
    """How many samples of the lab run the rig's effect moves by more than the noise's standard
    deviation: the rig run noise-free through the lab run with its effect and without it (same
    between-call behaviour). A log the effect never touched cannot name it: for the recorded ways
    such a rig is a plain rig."""
    quiet = {**params, "noise": {**params["noise"], "std": 0.0}}
    runs = []
    for effect in (params["effect"], "none"):
        state: dict = {}
        p = json.loads(json.dumps({**quiet, "effect": effect}))
        runs.append(np.concatenate([rigkit.run(p, state, u, b["dt"]) for u in lab_inputs(b)]))
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


RIG = '''"""A hidden rig of the blind diagnosis check (generated)."""
import json
import rigkit

PARAMS = json.loads({params!r})
STATE = {{}}


def rig(u, dt):
    return rigkit.run(PARAMS, STATE, u, dt)
'''


def generate(out: Path, n_cases: int = 40, seed: int = 2024, recorded: bool = False,
             effect: str | None = None) -> list[str]:
    """The cases of ``seed``; with ``effect``, every case carries that effect (a development set
    for one family: its labels are known, never a judged seed)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ss = np.random.SeedSequence(seed)
    rng = np.random.default_rng(ss.spawn(1)[0])
    labels = ["none"] * 6 + [e for e in CATALOGUE for _ in range(3)]
    outside = ["hysteretic_friction"] * 3 + ["gain_drift"] * 2 + ["second_nonlinearity"] * 2
    labels += outside
    labels = labels[:n_cases] if n_cases <= len(labels) else labels + list(rng.choice(CATALOGUE, n_cases - len(labels)))
    if effect is not None:
        labels = [effect] * n_cases
    rng.shuffle(labels)
    bases = list(BASES)
    sealed = {}
    ids = []
    case_seeds = ss.spawn(len(labels))
    # the lab runs' own random numbers (jitter, scales, pauses): spawned after everything else, so
    # the rigs, configs and labels for a seed are the same with or without --recorded
    lab_seeds = ss.spawn(1)[0].spawn(len(labels))
    lab_log = {}
    for i, label in enumerate(labels):
        if label == "second_nonlinearity":
            base = ["paper", "third_order"][i % 2]
        else:
            base = bases[int(rng.integers(len(bases)))]
        b = BASES[base]
        cid = f"c{i:02d}"
        d = out / cid
        d.mkdir(exist_ok=True)
        ep = effect_params(label, b, rng)
        between = str(rng.choice(BETWEEN_CALLS))
        actuator = str(rng.choice(["carry", "reset"]))
        params = {"F": b["F"], "G": b["G"], "h": b["h"], "noise": b["noise"], "effect": label,
                  "effect_params": ep, "seed": int(case_seeds[i].generate_state(1)[0]),
                  "between_calls": between, "actuator": actuator, "levels": list(b["levels"])}
        (d / f"rig_{cid}.py").write_text(RIG.format(params=json.dumps(params)))
        lo, hi = b["levels"]
        up = np.round(np.linspace(lo, hi, 10), 4).tolist()
        down = np.round(np.linspace(hi, lo, 11), 4).tolist()
        cfg = {"name": f"blind-{cid}", "seed": 7 + i, "sampling": {"dt": b["dt"]},
               "plant": {"kind": "external", "callable": f"rig_{cid}:rig"},
               "protocols": {"staircase": {"levels_up": up, "levels_down": down, "hold": b["hold"]},
                             "sine": {"amplitude": b["amp"], "frequencies": b["freqs"], "periods": b["periods"],
                                      "lead_in_periods": 1}}}
        (d / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
        model = {"plant": {"kind": "hammerstein_wiener", "input_nonlinearity": b["F"],
                           "linear": {"num": b["G"]["num"], "den": b["G"]["den"]},
                           "output_nonlinearity": {"polynomial": b["h"]}, "noise": b["noise"]}}
        (d / "model.yaml").write_text(yaml.safe_dump(model, sort_keys=False))
        if recorded:
            run = lab_run(json.loads(json.dumps(params)), b, np.random.default_rng(lab_seeds[i]))
            lab_log[cid] = {"base": base, **write_lab(d, cid, i, b, run)}
        sealed[cid] = {"label": label, "base": base, "params": ep, "between_calls": between, "actuator": actuator}
        if recorded:
            sealed[cid]["lab_footprint"] = lab_footprint(params, b)
        ids.append(cid)
    (out / "sealed.json").write_text(json.dumps(sealed, indent=1))
    if recorded:
        for base in BASES:
            seen = [v for v in lab_log.values() if v["base"] == base]
            if seen:
                print(f"lab run, {base} base: {seen[0]['rig_seconds']:.0f} rig-s, {seen[0]['rows']} rows "
                      f"(parts {seen[0]['parts']}), {len(seen)} case(s)")
    return ids


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--recorded", action="store_true",
                    help="also write lab.csv (one ordinary lab run of each rig) and recorded.yaml per case")
    ap.add_argument("--effect", choices=CATALOGUE + OUTSIDE + ["none"],
                    help="development only: every case carries this effect (the labels are then known)")
    a = ap.parse_args()
    print(f"{len(generate(Path(a.out), a.cases, a.seed, a.recorded, a.effect))} cases in {a.out} "
          "(labels sealed in sealed.json)")
