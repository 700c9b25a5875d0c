"""The STS3215 servo logs, every log and motor under test: hwid's stage 1 from a plain config beside
the authors' push-through figures and the settled gap read off the log (issue 45, item 5).

Data: ../shared/data/real/sts3215/ (CC BY 4.0, roboninecom/Measuring-Backlash-in-Popular-UART-Servos
@5273b56, ``logs/``). Three figures per row, each a different quantity, all in encoder counts
(4096 a turn):

* **hwid** -- ``hwid identify-nonlinear`` on ``configs/sts3215/<log>_m<motor>.yaml`` (the motor's
  target in, its position out, nothing else): the dead band ``d+ - d-`` of stage 1
  (:mod:`hwid.identify.history`) with its 95 % interval, and what the fit can be trusted for:
  ``adequate`` (the levels' chi-square judges the model and accepts it), ``misfit`` (it rejects
  it), ``undetermined`` (too few distinct levels to judge it, :mod:`hwid.identify.determinable`),
  or the dead band itself undetermined, with the reason.
* **authors, stretched / relaxed** -- the authors' ``log_calc.py`` (``software/logs_analysis``,
  configs ``config_m5.json``, ``config_m1_m2.json``, ``config_m4.json``) reimplemented here: while
  every motor under test holds its home target (2047), the mean position of the motor under test
  while one puller holds its stretch target (within its tolerance), against that while the other
  does ("stretched"); and the same over the first stretch after each pull in which both pullers are
  back at their relaxed targets within 4 counts ("relaxed"). The play the pullers push the output
  through, the servo's position loop holding the motor.
* **settled gap** -- at the home target, the position the servo settles to when it comes from
  above minus that when it comes from below, each read as the last 3 samples of the first flat
  stretch after the target step in which both pullers are relaxed (before any pull); averaged over
  the home holds from each side. What target-to-position map the servo shows without a load: the
  quantity stage 1's dead band estimates.

Usage: ``python experiments/real/sts3215_table.py [--write]``; ``--write`` also writes
``docs/tutorials/sts3215_table.md`` (a generated fragment).
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[2]
FOLDER = next((p for p in (ROOT.parent / "shared" / "data" / "real" / "sts3215",
                           ROOT.parents[1] / "shared" / "data" / "real" / "sts3215") if p.is_dir()),
              ROOT.parent / "shared" / "data" / "real" / "sts3215")
OUT = ROOT / "docs" / "tutorials" / "sts3215_table.md"
HOME = 2047

#: the authors' analysis configs (log_calc.py): motors under test, pullers (relaxed, stretched, tolerance)
AUTHORS = {
    "m5": {"home": [5], "pullers": {3: (1747, 2147, 100), 4: (2347, 1947, 100)}},
    "m1_m2": {"home": [1, 2], "pullers": {3: (1747, 2247, 100), 4: (2347, 1847, 100)}},
    "m4": {"home": [4], "pullers": {1: (2347, 1947, 200), 2: (1747, 2147, 200)}},
}
#: (log, motor under test, the authors' config for that log)
CASES = [("single", 5, "m5"), ("nocomp2", 1, "m1_m2"), ("nocomp2", 2, "m1_m2"), ("comp2", 1, "m1_m2"),
         ("comp2", 2, "m1_m2"), ("single_3250", 4, "m4")]
RELAXED_TOL, MIN_SEGMENT = 4, 10


def csv_path(log: str) -> Path:
    return FOLDER / f"motor_telemetry_{log}.csv"


def _runs(mask) -> list[tuple[int, int]]:
    """``[start, stop)`` stretches where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, int), 0]))
    return list(zip(edges[::2], edges[1::2]))


def _relaxed(df: pd.DataFrame, pullers: dict) -> np.ndarray:
    ok = np.ones(len(df), bool)
    for m, (relaxed, _, _) in pullers.items():
        ok &= (df[f"target pos ({m})"] == relaxed).to_numpy() & (np.abs(df[f"pos ({m})"] - relaxed) <= RELAXED_TOL).to_numpy()
    return ok


def authors_play(df: pd.DataFrame, motor: int, config: str) -> dict:
    """The authors' stretched and relaxed deviation of ``motor`` (module docstring; log_calc.py)."""
    cfg = AUTHORS[config]
    phase = np.ones(len(df), bool)
    for m in cfg["home"]:
        phase &= (df[f"target pos ({m})"] == HOME).to_numpy()
    relaxed = _relaxed(df, cfg["pullers"])
    pos = df[f"pos ({motor})"].to_numpy(float)
    groups = {(m, s): [] for m in cfg["pullers"] for s in ("stretched", "relaxed")}
    for a, b in _runs(phase):
        if b - a < MIN_SEGMENT:
            continue
        rel = _runs(relaxed[a:b])
        for m, (_, stretch, tol) in cfg["pullers"].items():
            pulling = (df[f"target pos ({m})"] == stretch).to_numpy() & (np.abs(df[f"pos ({m})"] - stretch) <= tol).to_numpy()
            for sa, sb in _runs(pulling[a:b]):
                groups[m, "stretched"].append(pos[a + sa:a + sb])
                after = [(ra, rb) for ra, rb in rel if ra > sb - 1]
                if after:
                    groups[m, "relaxed"].append(pos[a + after[0][0]:a + after[0][1]])
    out = {}
    for state in ("stretched", "relaxed"):
        means = [float(np.nanmean(np.concatenate(groups[m, state]))) for m in cfg["pullers"] if groups[m, state]]
        out[state] = abs(means[0] - means[1]) if len(means) == 2 else float("nan")
    return out


def settled_gap(df: pd.DataFrame, motor: int, config: str) -> dict:
    """At the home target: the settled position approached from above minus that from below, each
    the last 3 samples of the first flat relaxed stretch after the step (module docstring)."""
    target = df[f"target pos ({motor})"].to_numpy(float)
    pos = df[f"pos ({motor})"].to_numpy(float)
    relaxed = _relaxed(df, AUTHORS[config]["pullers"])
    change = np.r_[0, np.flatnonzero(np.diff(target) != 0) + 1, target.size]
    side = {"below": [], "above": []}
    for k in range(1, change.size - 1):
        a, b = change[k], change[k + 1]
        if target[a] != HOME or not np.isfinite(target[a - 1]):
            continue
        for ra, rb in _runs(relaxed[a:b]):
            tail = pos[a + ra:a + rb][-3:]
            if rb - ra >= 4 and np.all(np.isfinite(tail)) and np.ptp(tail) == 0:
                side["below" if target[a - 1] < HOME else "above"].append(float(tail.mean()))
                break
    gap = np.mean(side["above"]) - np.mean(side["below"]) if side["above"] and side["below"] else float("nan")
    return {"gap": float(gap), "below": side["below"], "above": side["above"]}


def plain_config(log: str, motor: int, folder: Path):
    """``configs/sts3215/<log>_m<motor>.yaml`` as a user runs it; where its relative path to the data
    does not resolve (a checkout elsewhere), the same config pointed at ``FOLDER``."""
    from hwid.config import load
    path = ROOT / "configs" / "sts3215" / f"{log}_m{motor}.yaml"
    data = yaml.safe_load(path.read_text())
    exp = data["plant"]["experiments"][0]
    if (path.parent / exp["file"]).is_file():
        return load(path)
    exp["file"] = str(FOLDER / Path(exp["file"]).name)
    moved = folder / path.name
    moved.write_text(yaml.safe_dump(data, sort_keys=False))
    return load(moved)


def hwid_stage1(log: str, motor: int):
    """hwid's stage 1 on the plain config, as ``hwid identify-nonlinear`` runs it."""
    from hwid.identify.history import identify_recorded
    from hwid.recorded import load_records
    with tempfile.TemporaryDirectory() as tmp:
        cfg = plain_config(log, motor, Path(tmp))
        return identify_recorded(cfg, load_records(cfg))


def trust(res) -> str:
    """``adequate``, ``misfit`` or ``undetermined`` and why (module docstring)."""
    und = res.undetermined
    if "dead_band" in und:
        return f"dead band undetermined: {und['dead_band']}"
    if res.misfit:
        return f"misfit: chi2 = {res.chi2:.3g} on {res.dof} dof (p = {res.p_value:.2g})"
    if "adequacy" in und:
        return "fit undetermined: " + und["adequacy"].split(":")[0]
    return f"adequate: chi2 = {res.chi2:.3g} on {res.dof} dof (p = {res.p_value:.2g})"


def rows() -> list[dict]:
    out = []
    for log, motor, config in CASES:
        df = pd.read_csv(csv_path(log))
        res = hwid_stage1(log, motor)
        out.append({"log": log, "motor": motor, "res": res, "authors": authors_play(df, motor, config),
                    "gap": settled_gap(df, motor, config), "pushes": sum("the output moved by" in w for w in res.warnings)})
    return out


def markdown(table: list[dict]) -> str:
    lines = ["<!-- generated by experiments/real/sts3215_table.py --write; do not edit -->",
             "| log | motor | hwid: dead band [95 %] (counts) | hwid: trust | holds cut at a push | "
             "authors: stretched | authors: relaxed | settled gap at home (from above - from below) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in table:
        res, ci = r["res"], r["res"].ci["dead_band"]
        band = f"{res.dead_band:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]" if ci is not None else "undetermined"
        g = r["gap"]
        lines.append(f"| {r['log']} | M{r['motor']} | {band} ({res.type}) | {trust(res)} | {r['pushes']} | "
                     f"{r['authors']['stretched']:.2f} | {r['authors']['relaxed']:.2f} | {g['gap']:.2f} "
                     f"({len(g['above'])} / {len(g['below'])} holds) |")
    return "\n".join(lines) + "\n"


def main(argv) -> None:
    if not FOLDER.is_dir():
        raise SystemExit(f"the STS3215 logs are not at {FOLDER}")
    text = markdown(rows())
    print(text)
    if "--write" in argv:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        tmp = OUT.with_name(OUT.name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, OUT)
        print(f"wrote {OUT}")


if __name__ == "__main__":
    main(sys.argv[1:])
