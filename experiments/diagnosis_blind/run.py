"""Blind check of ``hwid diagnose``: run it on every hidden rig through the CLI, like a user, then
open the sealed labels and score.

Usage::

    python generate.py /tmp/blind
    python run.py /tmp/blind --way model      # the rig's own simulator as --model
    python run.py /tmp/blind --way identify   # no --model: hwid identifies the model first

Prints a confusion matrix (truth rows, verdict columns; effects outside the catalogue are one row,
``outside``), the accuracy (an outside effect counts as correct when called ``unexplained``), false
alarms on plain rigs, gap after / noise floor for correct verdicts, and time, plant calls and
rig-seconds per diagnosis. Writes ``RESULTS-<way>.json`` beside the cases.
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
CATALOGUE = ["input_saturation", "rate_limit", "input_deadzone", "curved_borders", "time_delay",
             "resonance", "sensor_lag", "sensor_saturation", "drift"]


def diagnose_case(case: Path, way: str) -> dict:
    out = case / f"out-{way}"
    js = case / f"diagnosis-{way}.json"
    cmd = [sys.executable, "-m", "hwid", "diagnose", str(case / "config.yaml"), "--out", str(out), "--json", str(js)]
    if way == "model":
        cmd[4:4] = ["--model", str(case / "model.yaml")]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(case), str(HERE), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        return {"case": case.name, "error": (p.stderr or p.stdout).strip().splitlines()[-1:], "seconds": dt}
    s = json.loads(js.read_text())
    return {"case": case.name, "seconds": dt, "verdict": s["verdict"], "gap_before": s["gap_before"],
            "gap_after": s["gap_after"], "noise_floor": s["noise_floor"], "cost": s["cost"],
            "top": [(c["effect"], round(c["explained_fraction"], 3)) for c in s["candidates"][:3]],
            "region": s["where"]["region"], "trend": s["where"]["trend"]}


def score(results: list[dict], sealed: dict) -> dict:
    rows = ["none"] + CATALOGUE + ["outside"]
    cols = ["none"] + CATALOGUE + ["unexplained", "error"]
    M = {r: {c: 0 for c in cols} for r in rows}
    correct, ratios, details = 0, [], []
    for r in results:
        truth = sealed[r["case"]]["label"]
        row = truth if truth in rows else "outside"
        got = "error" if "error" in r else r["verdict"]["effect"]
        M[row][got] += 1
        ok = (got == truth) or (row == "outside" and got == "unexplained")
        correct += ok
        if ok and got in CATALOGUE:
            ratios.append(r["gap_after"] / r["noise_floor"])
        details.append({**r, "truth": truth, "base": sealed[r["case"]]["base"], "truth_params": sealed[r["case"]]["params"],
                        "correct": bool(ok)})
    n_none = sum(M["none"].values())
    n_out = sum(M["outside"].values())
    ok_runs = [r for r in results if "error" not in r]
    return {"matrix": M, "rows": rows, "cols": cols, "n": len(results), "correct": int(correct),
            "accuracy": correct / max(len(results), 1),
            "false_alarms_on_none": n_none - M["none"]["none"], "n_none": n_none,
            "outside_unexplained": M["outside"]["unexplained"], "n_outside": n_out,
            "gap_after_over_noise_correct": {"max": max(ratios, default=float("nan")),
                                             "median": float(np.median(ratios)) if ratios else float("nan"),
                                             "within_1.5": int(sum(x <= 1.5 for x in ratios)), "n": len(ratios)},
            "seconds": {"median": float(np.median([r["seconds"] for r in results])),
                        "max": float(max(r["seconds"] for r in results))},
            "plant_calls": {"median": float(np.median([r["cost"]["plant_calls_identification"] + r["cost"]["plant_calls_validation"] for r in ok_runs])) if ok_runs else 0},
            "rig_seconds": {"median": float(np.median([r["cost"]["rig_seconds_identification"] + r["cost"]["rig_seconds_validation"] for r in ok_runs])) if ok_runs else 0},
            "details": details}


def print_table(sc: dict, way: str) -> None:
    short = {"none": "none", "input_saturation": "in_sat", "rate_limit": "rate", "input_deadzone": "dz",
             "curved_borders": "curv", "time_delay": "delay", "resonance": "reso", "sensor_lag": "lag",
             "sensor_saturation": "y_sat", "drift": "drift", "unexplained": "unexp", "error": "err", "outside": "outside"}
    print(f"\nblind check, way = {way}: {sc['correct']}/{sc['n']} correct ({100 * sc['accuracy']:.0f} %)")
    print("truth \\ verdict".ljust(18) + "".join(short[c].rjust(7) for c in sc["cols"]))
    for r in sc["rows"]:
        if sum(sc["matrix"][r].values()) == 0:
            continue
        print(short[r].ljust(18) + "".join((str(sc["matrix"][r][c]) if sc["matrix"][r][c] else ".").rjust(7) for c in sc["cols"]))
    print(f"false alarms on plain rigs: {sc['false_alarms_on_none']}/{sc['n_none']}")
    print(f"outside effects called unexplained: {sc['outside_unexplained']}/{sc['n_outside']}")
    g = sc["gap_after_over_noise_correct"]
    print(f"correct verdicts with gap after <= 1.5 x noise floor: {g['within_1.5']}/{g['n']} "
          f"(median {g['median']:.2f}, max {g['max']:.2f})")
    print(f"per diagnosis: median {sc['seconds']['median']:.0f} s, max {sc['seconds']['max']:.0f} s wall; "
          f"median {sc['plant_calls']['median']:.0f} plant calls, {sc['rig_seconds']['median']:.0f} rig-seconds")
    for d in sc["details"]:
        if not d["correct"]:
            print(f"  wrong: {d['case']} ({d['base']}) truth {d['truth']} {d['truth_params']} -> "
                  f"{d.get('verdict', d.get('error'))} top {d.get('top')}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cases")
    ap.add_argument("--way", choices=["model", "identify"], default="model")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", help="case ids (default: all)")
    a = ap.parse_args()
    root = Path(a.cases)
    cases = sorted(p for p in root.iterdir() if p.is_dir() and (p / "config.yaml").exists())
    if a.only:
        cases = [c for c in cases if c.name in a.only]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(a.jobs) as ex:
        results = []
        for r in ex.map(lambda c: diagnose_case(c, a.way), cases):
            print(f"{r['case']}: {r.get('verdict', r.get('error'))} ({r['seconds']:.0f} s)", flush=True)
            results.append(r)
    # only now: the labels
    sealed = json.loads((root / "sealed.json").read_text())
    sc = score(results, sealed)
    sc["wall_seconds"] = time.perf_counter() - t0
    print_table(sc, a.way)
    (root / f"RESULTS-{a.way}.json").write_text(json.dumps(sc, indent=1, default=str))


if __name__ == "__main__":
    main()
