"""Blind check of ``hwid diagnose``: run it on every hidden rig through the CLI, like a user, then
open the sealed labels and score.

Usage::

    python generate.py /tmp/blind
    python run.py /tmp/blind --way model      # the rig's own simulator as --model
    python run.py /tmp/blind --way identify   # no --model: hwid identifies the model first

    python generate.py /tmp/blind --recorded  # also lab.csv + recorded.yaml per case
    python run.py /tmp/blind --way recorded-model     # the lab log as the plant, the rig's simulator as --model
    python run.py /tmp/blind --way recorded-identify  # the lab log only: hwid identifies from it first

Prints a confusion matrix (truth rows, verdict columns; effects and disturbances outside the
catalogue are one row, ``outside``, broken down by label below it), the accuracy (an outside effect
counts as correct when called ``unexplained``), the share correct per base, false alarms on plain
rigs, gap after / noise floor for correct verdicts, and time, plant calls and rig-seconds per
diagnosis. Writes ``RESULTS-<way>.json`` beside the cases.

The recorded ways (``recorded-model``, ``recorded-identify``) diagnose ``CASE/recorded.yaml`` (one
logged lab run of the rig, no plant calls). Their verdicts are scored as above, and also with half
credit: a catalogue effect that is not the verdict but is in the verdict's
``indistinguishable_from`` counts one half.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from generate import CATALOGUE, LAB_VISIBLE_SAMPLES  # noqa: E402
#: every effect the diagnosis can name, whether or not this generator draws it
NAMED = CATALOGUE + [e for e in ("friction", "output_hysteresis") if e not in CATALOGUE]
#: outside labels whose operator is of a catalogue class: naming that class is right too
#: (``hysteretic_friction`` is one play on the output after h, ``output_hysteresis``'s operator)
ALSO_RIGHT = {"hysteretic_friction": ("output_hysteresis",)}
WAYS = ["model", "identify", "recorded-model", "recorded-identify"]


def _config(way: str) -> str:
    """The case's config a way diagnoses: the rig (``config.yaml``) or its lab log (``recorded.yaml``)."""
    return "recorded.yaml" if way.startswith("recorded") else "config.yaml"


def diagnose_case(case: Path, way: str) -> dict:
    out = case / f"out-{way}"
    js = case / f"diagnosis-{way}.json"
    cmd = [sys.executable, "-m", "hwid", "diagnose", str(case / _config(way)), "--out", str(out), "--json", str(js)]
    if way in ("model", "recorded-model"):
        cmd[4:4] = ["--model", str(case / "model.yaml")]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(case), str(HERE), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        return {"case": case.name, "error": (p.stderr or p.stdout).strip().splitlines()[-1:], "seconds": dt}
    s = json.loads(js.read_text())
    where = s.get("where") or {}
    return {"case": case.name, "seconds": dt, "verdict": s["verdict"], "gap_before": s.get("gap_before"),
            "gap_after": s.get("gap_after"), "noise_floor": s.get("noise_floor"), "cost": s.get("cost") or {},
            "top": [(c["effect"], round(c["explained_fraction"], 3)) for c in s.get("candidates", [])[:3]],
            "region": where.get("region"), "trend": where.get("trend")}


def _calls(cost: dict) -> float:
    """Plant calls of a diagnosis (none for a recorded one)."""
    return cost.get("plant_calls_identification", 0) + cost.get("plant_calls_validation", 0)


def _rig_seconds(cost: dict) -> float:
    return cost.get("rig_seconds_identification", 0) + cost.get("rig_seconds_validation", 0)


def score(results: list[dict], sealed: dict, half_credit: bool = False) -> dict:
    """The table; with ``half_credit`` (the recorded ways) also ``credit``: a catalogue truth that is
    not the verdict but in its ``indistinguishable_from`` counts 0.5 (``halves`` of them)."""
    rows = ["none"] + CATALOGUE + ["outside"]
    cols = ["none"] + NAMED + ["unexplained", "error"]
    M = {r: {c: 0 for c in cols} for r in rows}
    correct, ratios, details = 0, [], []
    credit, halves = 0.0, 0
    unseen = 0
    for r in results:
        truth = sealed[r["case"]]["label"]
        foot = sealed[r["case"]].get("lab_footprint")
        if half_credit and truth != "none" and foot is not None and foot < LAB_VISIBLE_SAMPLES:
            truth, unseen = "none", unseen + 1    # the lab log never shows the effect: a plain rig here
        row = truth if truth in rows else "outside"
        got = "error" if "error" in r else r["verdict"]["effect"]
        M[row][got if got in M[row] else "error"] += 1
        ok = (got == truth) or (row == "outside" and got in ("unexplained",) + ALSO_RIGHT.get(truth, ()))
        correct += ok
        alike = [] if "error" in r else list(r["verdict"].get("indistinguishable_from") or [])
        half = (not ok) and truth in CATALOGUE and truth in alike
        credit += 1.0 if ok else (0.5 if half else 0.0)
        halves += bool(half)
        if ok and got in NAMED and r.get("gap_after") is not None and r.get("noise_floor"):
            ratios.append(r["gap_after"] / r["noise_floor"])
        details.append({**r, "truth": truth, "base": sealed[r["case"]]["base"], "truth_params": sealed[r["case"]]["params"],
                        "correct": bool(ok), **({"credit": 1.0 if ok else (0.5 if half else 0.0)} if half_credit else {})})
    by_base, outside_by_label = {}, {}
    for d in details:
        nb = by_base.setdefault(d["base"], {"n": 0, "correct": 0})
        nb["n"], nb["correct"] = nb["n"] + 1, nb["correct"] + d["correct"]
        label = sealed[d["case"]]["label"]
        if label not in rows and d["truth"] != "none":
            nl = outside_by_label.setdefault(label, {"n": 0, "unexplained": 0})
            nl["n"], nl["unexplained"] = nl["n"] + 1, nl["unexplained"] + d["correct"]
    n_none = sum(M["none"].values())
    n_out = sum(M["outside"].values())
    ok_runs = [r for r in results if "error" not in r]
    extra = {"credit": credit, "halves": halves, "accuracy_half_credit": credit / max(len(results), 1),
             "effect_not_in_log": unseen} if half_credit else {}
    return {"matrix": M, "rows": rows, "cols": cols, "n": len(results), "correct": int(correct),
            "accuracy": correct / max(len(results), 1), **extra,
            "false_alarms_on_none": n_none - M["none"]["none"], "n_none": n_none,
            "outside_unexplained": M["outside"]["unexplained"], "n_outside": n_out,
            "by_base": by_base, "outside_by_label": outside_by_label,
            "gap_after_over_noise_correct": {"max": max(ratios, default=float("nan")),
                                             "median": float(np.median(ratios)) if ratios else float("nan"),
                                             "within_1.5": int(sum(x <= 1.5 for x in ratios)), "n": len(ratios)},
            "seconds": {"median": float(np.median([r["seconds"] for r in results])),
                        "max": float(max(r["seconds"] for r in results))},
            "plant_calls": {"median": float(np.median([_calls(r["cost"]) for r in ok_runs])) if ok_runs else 0},
            "rig_seconds": {"median": float(np.median([_rig_seconds(r["cost"]) for r in ok_runs])) if ok_runs else 0},
            "details": details}


def print_table(sc: dict, way: str) -> None:
    short = {"none": "none", "input_saturation": "in_sat", "rate_limit": "rate", "input_deadzone": "dz",
             "curved_borders": "curv", "time_delay": "delay", "resonance": "reso", "sensor_lag": "lag",
             "sensor_saturation": "y_sat", "drift": "drift", "friction": "fric", "output_hysteresis": "y_hyst", "unexplained": "unexp", "error": "err", "outside": "outside"}
    print(f"\nblind check, way = {way}: {sc['correct']}/{sc['n']} correct ({100 * sc['accuracy']:.0f} %)")
    if "credit" in sc:
        print(f"correct (half credit for indistinguishable): {sc['credit']:g}/{sc['n']} "
              f"({100 * sc['accuracy_half_credit']:.0f} %), {sc['halves']} half(s)")
        print(f"rigs whose effect moves fewer than {LAB_VISIBLE_SAMPLES} samples of the lab log by more than the "
              f"noise (scored as plain rigs): {sc['effect_not_in_log']}")
    print("truth \\ verdict".ljust(18) + "".join(short[c].rjust(7) for c in sc["cols"]))
    for r in sc["rows"]:
        if sum(sc["matrix"][r].values()) == 0:
            continue
        print(short[r].ljust(18) + "".join((str(sc["matrix"][r][c]) if sc["matrix"][r][c] else ".").rjust(7) for c in sc["cols"]))
    print(f"false alarms on plain rigs: {sc['false_alarms_on_none']}/{sc['n_none']}")
    print(f"outside effects called unexplained: {sc['outside_unexplained']}/{sc['n_outside']}"
          + "".join(f"; {k} {v['unexplained']}/{v['n']}" for k, v in sorted(sc["outside_by_label"].items())))
    print("correct by base: " + ", ".join(f"{k} {v['correct']}/{v['n']}" for k, v in sorted(sc["by_base"].items())))
    g = sc["gap_after_over_noise_correct"]
    print(f"correct verdicts with gap after <= 1.5 x noise floor: {g['within_1.5']}/{g['n']} "
          f"(median {g['median']:.2f}, max {g['max']:.2f})")
    print(f"per diagnosis: median {sc['seconds']['median']:.0f} s, max {sc['seconds']['max']:.0f} s wall; "
          f"median {sc['plant_calls']['median']:.0f} plant calls, {sc['rig_seconds']['median']:.0f} rig-seconds")
    for d in sc["details"]:
        if not d["correct"]:
            half = " [half credit: indistinguishable]" if d.get("credit") == 0.5 else ""
            print(f"  wrong: {d['case']} ({d['base']}) truth {d['truth']} {d['truth_params']} -> "
                  f"{d.get('verdict', d.get('error'))} top {d.get('top')}{half}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cases")
    ap.add_argument("--way", choices=WAYS, default="model")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", help="case ids (default: all)")
    ap.add_argument("--rescore", action="store_true", help="score the diagnoses saved in RAW-<way>.json again, "
                                                          "running none")
    a = ap.parse_args()
    root = Path(a.cases)
    raw = root / f"RAW-{a.way}.json"
    if a.rescore:
        report(root, a.way, json.loads(raw.read_text()), 0.0)
        return
    cases = sorted(p for p in root.iterdir() if p.is_dir() and (p / "config.yaml").exists())
    if a.way.startswith("recorded"):
        missing = [c.name for c in cases if not (c / "recorded.yaml").exists()]
        if missing:
            sys.exit(f"{len(missing)} case(s) without recorded.yaml (e.g. {missing[0]}): generate with --recorded")
    if a.only:
        cases = [c for c in cases if c.name in a.only]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(a.jobs) as ex:
        results = []
        for r in ex.map(lambda c: diagnose_case(c, a.way), cases):
            print(f"{r['case']}: {r.get('verdict', r.get('error'))} ({r['seconds']:.0f} s)", flush=True)
            results.append(r)
    raw.write_text(json.dumps(results, indent=1, default=str))   # kept before the labels are opened
    report(root, a.way, results, time.perf_counter() - t0)


def hwid_commit() -> str:
    """The commit of the hwid checkout the diagnoses ran (the one ``python -m hwid`` imports here),
    ``+changes`` where its tree differs."""
    import importlib.util
    spec = importlib.util.find_spec("hwid")
    if spec is None or spec.origin is None:
        return "unknown"
    sys.path.insert(0, str(HERE.parents[1] / "docs"))
    from fragment import commit
    return commit(Path(spec.origin).resolve().parents[1])


def report(root: Path, way: str, results: list[dict], wall: float) -> None:
    """Only now: the labels; the table and ``RESULTS-<way>.json``."""
    sealed = json.loads((root / "sealed.json").read_text())
    sc = score(results, sealed, half_credit=way.startswith("recorded"))
    sc["wall_seconds"] = wall
    sc["hwid_commit"] = hwid_commit()
    print_table(sc, way)
    (root / f"RESULTS-{way}.json").write_text(json.dumps(sc, indent=1, default=str))


if __name__ == "__main__":
    main()
