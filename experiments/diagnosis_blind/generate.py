"""Generator of hidden rigs for the blind check of ``hwid diagnose``.

Each case is a directory with

* ``rig_<id>.py`` -- an external-plant driver ``rig(u, dt) -> y`` (``plant.kind: external``) built on
  :mod:`rigkit` (numpy/scipy only, written apart from hwid): a base plant (:mod:`bases`) plus none,
  one catalogue effect at a random strength, or an effect or disturbance outside the catalogue;
* ``config.yaml`` -- the config a user would write for that rig (identification protocols);
* ``model.yaml`` -- the rig's own simulator without the effect (the sim side for ``--model``).

With ``--recorded`` each case also gets ``lab.csv`` -- one ordinary lab session of the hidden rig,
logged like a lab logs (:mod:`labrun`) -- and ``recorded.yaml``, the recorded-plant config a lab user
would write for that file.

Two draws: ``--mix wide`` (the default, 50 cases: seven bases, five between-call behaviours, the
eleven catalogue effects, outside effects and disturbances, lab sessions with uneven holds and cut
parts) and ``--mix classic`` (``--classic``; 40 cases as the generator drew them before: four
fixed bases, nine catalogue effects, even lab holds -- the same rigs and logs for the same seed).

The labels go to ``sealed.json`` beside the cases, which the runner opens only after every
diagnosis is done. Usage: ``python generate.py OUTDIR [--cases N] [--seed 2024] [--recorded]
[--mix wide|classic] [--effect NAME] [--base NAME]``.
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
import bases  # noqa: E402
from bases import h_slope, gain_at  # noqa: E402
from bases import v_range as _v_range, w_range as _w_range, y_range as _y_range  # noqa: E402
from labrun import LAB_VISIBLE_SAMPLES, lab_footprint, lab_inputs, lab_layout, lab_run, write_lab  # noqa: E402,F401

#: the catalogue effects of the classic draw
CLASSIC_CATALOGUE = ["input_saturation", "rate_limit", "input_deadzone", "curved_borders", "time_delay",
                     "resonance", "sensor_lag", "sensor_saturation", "drift"]
#: every effect the diagnosis's catalogue names: right when the verdict names it
CATALOGUE = CLASSIC_CATALOGUE + ["friction", "output_hysteresis"]
#: outside the catalogue: right only when the verdict is ``unexplained`` (run.py's ``outside`` row).
#: ``periodic_load`` and ``gain_step`` are disturbances, not effects of the chain
CLASSIC_OUTSIDE = ["hysteretic_friction", "gain_drift", "second_nonlinearity"]
OUTSIDE = CLASSIC_OUTSIDE + ["periodic_load", "gain_step"]
# what a rig does between calls (rigkit's module docstring)
BETWEEN_CALLS = ["carry", "parked", "anywhere"]
WIDE_BETWEEN_CALLS = BETWEEN_CALLS + ["keep", "reset"]
#: the wide draw's 50 labels: plain rigs (spread over every base), 3 of each catalogue effect, and
#: 9 outside effects and disturbances
WIDE_MIX = {"none": 8, **{e: 3 for e in CATALOGUE}, "hysteretic_friction": 2, "gain_drift": 2,
            "second_nonlinearity": 1, "periodic_load": 2, "gain_step": 2}
MIXES = ["wide", "classic"]
#: the fixed bases as the classic draw knows them
BASES = bases.FIXED


#: the shapes a bent border takes (rigkit._bow): symmetric and odd bends, S-curves, one-sided
#: stiffening, a local bump -- any smooth shape, not one family's own
BOW_SHAPES = ["sine", "parabola", "cubic", "s_curve", "one_sided", "bump"]
#: friction laws (rigkit._friction_g)
FRICTION_LAWS = ["dahl", "lugre", "coulomb_tanh"]


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
    if effect in NEW_EFFECTS:
        return NEW_EFFECTS[effect](b, rng)
    if effect == "none":
        return {}
    raise ValueError(effect)


def session_seconds(b: dict) -> float:
    """The shorter of the config's protocols (both staircases, every sine with its lead-in) and the
    classic lab run: a rig-time that every way of running the rig passes."""
    stair = (10 + 11) * b["hold"]
    sines = sum((b["periods"] + 1) * 2 * np.pi / w for w in b["freqs"])
    lab = sum(u.size for u in lab_inputs(b)) * b["dt"]
    return float(min(stair + sines, lab))


def _friction(b: dict, rng: np.random.Generator) -> dict:
    """A friction law on G's output, referred to G's input: Coulomb level 2-8 % of the gear's output
    range, a pre-sliding deflection of 0.2-5 % of G's output range (bounded below so the bristles'
    stiffness stays resolved at dt), viscous up to half the Coulomb force at a typical velocity."""
    U = rng.uniform
    vlo, vhi = _v_range(b)
    wlo, whi = _w_range(b)
    Ww = whi - wlo
    law = str(rng.choice(FRICTION_LAWS))
    fc = (vhi - vlo) * _log_uniform(rng, 0.02, 0.08)
    vel = Ww * b["omega_c"] / 2
    fastest = float(np.max(np.abs(np.roots(b["G"]["den"]))))
    z_min = 2 * fc * abs(bases.dc_gain(b)) * b["dt"] * fastest
    zc = max(Ww * (_log_uniform(rng, 0.002, 0.02) if law == "lugre" else _log_uniform(rng, 0.01, 0.05)), z_min)
    p = {"law": law, "coulomb": fc, "z_c": zc, "viscous": U(0.0, 0.5) * fc / vel}
    if law == "lugre":
        p.update(stribeck=U(1.2, 1.8), v_s=vel * U(0.02, 0.1), sigma1_dt=U(0.0, 0.3))
    if law == "coulomb_tanh":
        p["v_eps"] = vel * U(0.005, 0.03)
    return p


def _output_hysteresis(b: dict, rng: np.random.Generator) -> dict:
    """A rate-independent hysteresis on G's output (``at: w``, before h: one play or a
    Prandtl-Ishlinskii sum) or on h's output (``at: y``: a Prandtl-Ishlinskii sum only -- one play
    there is the outside effect ``hysteretic_friction``); the loop's half-width (sum of weight x
    width) 2-6 % of that signal's range."""
    U = rng.uniform
    at = str(rng.choice(["w", "y"]))
    law = "pi" if at == "y" else str(rng.choice(["play", "pi"]))
    lo, hi = _w_range(b) if at == "w" else _y_range(b)
    half = (hi - lo) * U(0.02, 0.06)
    if law == "play":
        return {"at": at, "law": law, "widths": [half], "weights": [1.0], "linear": 0.0}
    n = int(rng.integers(3, 6))
    linear = U(0.2, 0.6)
    weights = (1 - linear) * rng.dirichlet(np.ones(n))
    shape = np.sort(U(0.2, 1.0, n))
    widths = shape * half / float(weights @ shape)
    return {"at": at, "law": law, "widths": widths.tolist(), "weights": weights.tolist(), "linear": linear}


def _periodic_load(b: dict, rng: np.random.Generator) -> dict:
    """A load at G's input at its own frequency (0.3-3 x the band, never within 20 % of a protocol
    or lab sine), 4-10 x the noise at the output."""
    for _ in range(100):
        omega = b["omega_c"] * _log_uniform(rng, 0.3, 3.0)
        if all(abs(omega / f - 1) > 0.2 for f in b["freqs"]):
            break
    size = b["noise"]["std"] * rng.uniform(4, 10)
    return {"omega": omega, "amp": size / (gain_at(b, omega) * h_slope(b)), "phase": rng.uniform(0, 2 * np.pi)}


def _gain_step(b: dict, rng: np.random.Generator) -> dict:
    """G's gain stepping once by 10-25 % either way, 30-70 % into the shorter session."""
    return {"at_s": rng.uniform(0.3, 0.7) * session_seconds(b),
            "step": float(rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.25))}


NEW_EFFECTS = {"friction": _friction, "output_hysteresis": _output_hysteresis,
               "periodic_load": _periodic_load, "gain_step": _gain_step}


RIG = '''"""A hidden rig of the blind diagnosis check (generated)."""
import json
import rigkit

PARAMS = json.loads({params!r})
STATE = {{}}


def rig(u, dt):
    return rigkit.run(PARAMS, STATE, u, dt)
'''




def _labels(mix: str, n_cases: int, effect: str | None, rng: np.random.Generator) -> list[str]:
    """The draw's labels, shuffled. The classic draw takes its list's first ``n_cases`` (as it
    always did); the wide draw a random ``n_cases`` of its 50; either tops a short list up with
    random catalogue effects."""
    if mix == "classic":
        labels = ["none"] * 6 + [e for e in CLASSIC_CATALOGUE for _ in range(3)]
        labels += ["hysteretic_friction"] * 3 + ["gain_drift"] * 2 + ["second_nonlinearity"] * 2
        labels = labels[:n_cases] if n_cases <= len(labels) else \
            labels + list(rng.choice(CLASSIC_CATALOGUE, n_cases - len(labels)))
    else:
        labels = [e for e, k in WIDE_MIX.items() for _ in range(k)]
        if n_cases < len(labels):
            labels = [str(x) for x in rng.choice(labels, n_cases, replace=False)]
        else:
            labels += [str(x) for x in rng.choice(CATALOGUE, n_cases - len(labels))]
    if effect is not None:
        labels = [effect] * n_cases
    rng.shuffle(labels)
    return labels


def _base_names(mix: str, labels: list[str], base: str | None, rng: np.random.Generator):
    """Yields each case's base name, drawing as the mix does: the classic draw uniformly over its
    four (a saturation between G's lags on the two bases with a split G, alternately); the wide
    draw spreads the plain rigs over every base and draws the others uniformly (the split G for a
    saturation between lags: every base but the asymmetric and inverse ones)."""
    if mix == "classic":
        for i, label in enumerate(labels):
            if base is not None:
                yield base
            elif label == "second_nonlinearity":
                yield ["paper", "third_order"][i % 2]
            else:
                yield bases.CLASSIC[int(rng.integers(len(bases.CLASSIC)))]
        return
    n_plain = labels.count("none")
    plain = [str(x) for x in rng.permutation(bases.ALL)] * (n_plain // len(bases.ALL) + 1)
    split = [n for n in bases.ALL if n in bases.DRAWN or "split" in bases.FIXED[n]]
    k = 0
    for label in labels:
        if base is not None:
            yield base
        elif label == "none":
            yield plain[k]
            k += 1
        elif label == "second_nonlinearity":
            yield split[int(rng.integers(len(split)))]
        else:
            yield bases.ALL[int(rng.integers(len(bases.ALL)))]


def _write_case(d: Path, cid: str, i: int, b: dict, params: dict) -> None:
    """The rig's driver, the user's config and the rig's own simulator without its effect."""
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


def generate(out: Path, n_cases: int | None = None, seed: int = 2024, recorded: bool = False,
             effect: str | None = None, mix: str = "wide", base: str | None = None) -> list[str]:
    """The cases of ``seed``; with ``effect`` (or ``base``), every case carries that effect (sits
    on that base): a development set whose labels are known, never a judged seed."""
    if mix not in MIXES:
        raise ValueError(f"mix must be one of {MIXES}")
    if effect == "second_nonlinearity" and base is not None and "split" not in bases.FIXED.get(base, {"split": 1}):
        raise ValueError(f"the {base} base has no split G for a saturation between its lags")
    n_cases = n_cases if n_cases is not None else (40 if mix == "classic" else sum(WIDE_MIX.values()))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ss = np.random.SeedSequence(seed)
    rng = np.random.default_rng(ss.spawn(1)[0])
    labels = _labels(mix, n_cases, effect, rng)
    between_calls = BETWEEN_CALLS if mix == "classic" else WIDE_BETWEEN_CALLS
    sealed, ids, lab_log = {}, [], {}
    case_seeds = ss.spawn(len(labels))
    # the lab runs' own random numbers (jitter, scales, pauses, the wide session's layout): spawned
    # after everything else, so the rigs, configs and labels are the same with or without --recorded
    lab_seeds = ss.spawn(1)[0].spawn(len(labels))
    for i, (label, name) in enumerate(zip(labels, _base_names(mix, labels, base, rng))):
        b = bases.draw(name, rng)
        cid = f"c{i:02d}"
        d = out / cid
        d.mkdir(exist_ok=True)
        ep = effect_params(label, b, rng)
        between = str(rng.choice(between_calls))
        actuator = str(rng.choice(["carry", "reset"]))
        params = {"F": b["F"], "G": b["G"], "h": b["h"], "noise": b["noise"], "effect": label,
                  "effect_params": ep, "seed": int(case_seeds[i].generate_state(1)[0]),
                  "between_calls": between, "actuator": actuator, "levels": list(b["levels"])}
        _write_case(d, cid, i, b, params)
        sealed[cid] = {"label": label, "base": name, "params": ep, "between_calls": between, "actuator": actuator}
        if name in bases.DRAWN:
            sealed[cid]["plant"] = {k: b[k] for k in ("F", "G", "h", "noise", "tau", "omega_c")}
        if recorded:
            lab_rng = np.random.default_rng(lab_seeds[i])
            layout = None if mix == "classic" else lab_layout(b, np.random.default_rng(lab_seeds[i].spawn(1)[0]))
            run = lab_run(json.loads(json.dumps(params)), b, lab_rng, layout)
            lab_log[cid] = {"base": name, **write_lab(d, cid, i, b, run)}
            sealed[cid]["lab_footprint"] = lab_footprint(params, b, layout)
            if layout is not None:
                sealed[cid]["lab"] = {"uneven_holds": layout["uneven"], "cut": layout["cut"]}
        ids.append(cid)
    (out / "sealed.json").write_text(json.dumps(sealed, indent=1))
    for name in bases.ALL:
        seen = [v for v in lab_log.values() if v["base"] == name]
        if seen:
            print(f"lab run, {name} base: {seen[0]['rig_seconds']:.0f} rig-s, {seen[0]['rows']} rows "
                  f"(parts {seen[0]['parts']}), {len(seen)} case(s)")
    return ids


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--cases", type=int, default=None, help="number of rigs (default 50 wide, 40 classic)")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--recorded", action="store_true",
                    help="also write lab.csv (one ordinary lab run of each rig) and recorded.yaml per case")
    ap.add_argument("--mix", choices=MIXES, default="wide",
                    help="wide (default): every base, effect and disturbance; classic: the earlier draw")
    ap.add_argument("--classic", action="store_true", help="the same as --mix classic")
    ap.add_argument("--effect", choices=CATALOGUE + OUTSIDE + ["none"],
                    help="development only: every case carries this effect (the labels are then known)")
    ap.add_argument("--base", choices=bases.ALL,
                    help="development only: every case sits on this base")
    a = ap.parse_args()
    mix = "classic" if a.classic else a.mix
    print(f"{len(generate(Path(a.out), a.cases, a.seed, a.recorded, a.effect, mix, a.base))} cases in {a.out} "
          "(labels sealed in sealed.json)")
