"""The STS3215 servo logs (../shared/data/real/sts3215/, CC BY 4.0, roboninecom/Measuring-Backlash-
in-Popular-UART-Servos): what hwid finds on them, side by side with the authors' own measurement.

The stand holds motor 5's target and pulls its output lever one way, then the other, with two
puller servos (motors 3 and 4); between pulls both pullers relax. Three figures, each a different
physical quantity:

* **authors, loaded / unloaded** -- the authors' definition, reimplemented here from their paper's
  description and ``log_calc.py`` (not copied): while motor 5's target is home (2047), the mean
  position of motor 5 while motor 3 pulls (target 2147, within 100 counts of it) against that while
  motor 4 pulls (target 1947); and the same over the first relaxed stretch after each pull (both
  pullers at their relaxed targets 1747 / 2347 and within 4 counts). This is the gear's play as a
  load moves the output through it, the servo's position loop holding the motor.
* **hwid, branch gap** -- the settled position at the same target approached from below and from
  above, before any pull (the relaxed samples right after the target step): what the servo's
  position loop and its gear together leave between the two directions of approach.
* **hwid, stage 1 from the log's levels** (:mod:`hwid.identify.history`) on the settled, unpushed
  levels picked here: the dead band ``d+ - d-`` of the backlash that maps target to measured
  position, with its 95 % interval and how far the fit can be trusted (``adequate``, ``misfit``,
  or ``undetermined`` where the levels leave no degree of freedom to judge it). hwid on the logs
  as recorded, from plain configs, with the pushes found by hwid itself:
  ``experiments/real/sts3215_table.py``.

Usage: ``python experiments/real/sts3215.py [CSV ...]`` (default: every log in the folder). The
roles are read from each log's targets (:func:`stands`: a puller's target takes two values, a
device under test's three); one table row per log and motor under test.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from hwid import HwidError
from hwid.identify.history import HistoryFit
from hwid.identify.result import Level

FOLDER = next((p for p in (Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "sts3215",
                         Path(__file__).resolve().parents[4] / "shared" / "data" / "real" / "sts3215") if p.is_dir()),
              Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "sts3215")
HOME, DUT = 2047, 5
PULLERS = {3: {"relaxed": 1747, "pull": 2147}, 4: {"relaxed": 2347, "pull": 1947}}
DEGREES_PER_COUNT = 360.0 / 4096


@dataclass(frozen=True)
class Stand:
    """Which motor is under test (its home target) and which pull (their relaxed and pull targets)."""

    dut: int = DUT
    home: int = HOME
    pullers: dict = field(default_factory=lambda: dict(PULLERS))


def stands(df: pd.DataFrame) -> list[Stand]:
    """Every motor under test of a log, as the log's targets show the roles: a puller's target
    takes two values (relaxed, the most frequent, and pull), a device under test's three (home,
    the most frequent, and a step either side)."""
    motors = sorted({int(c.split("(")[1].rstrip(")")) for c in df.columns if c.startswith("target pos (")})
    pullers, duts = {}, []
    for m in motors:
        counts = df[col("target pos", m)].dropna().value_counts()
        if len(counts) == 2:
            pullers[m] = {"relaxed": int(counts.index[0]), "pull": int(counts.index[1])}
        elif len(counts) >= 3:
            duts.append((m, int(counts.index[0])))
    return [Stand(m, home, pullers) for m, home in duts] if len(pullers) == 2 else []


def col(kind: str, motor: int) -> str:
    return f"{kind} ({motor})"


def relaxed(df: pd.DataFrame, stand: Stand = Stand()) -> np.ndarray:
    ok = np.ones(len(df), bool)
    for m, p in stand.pullers.items():
        ok &= (df[col("target pos", m)] == p["relaxed"]).to_numpy()
        ok &= (np.abs(df[col("pos", m)] - p["relaxed"]) <= 4).to_numpy()
    return ok


def pulling(df: pd.DataFrame, motor: int, stand: Stand = Stand()) -> np.ndarray:
    p = stand.pullers[motor]["pull"]
    return ((df[col("target pos", motor)] == p) & (np.abs(df[col("pos", motor)] - p) <= 100)).to_numpy()


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Contiguous ``[start, stop)`` stretches where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def authors(df: pd.DataFrame, stand: Stand = Stand()) -> dict:
    """Loaded and unloaded play of the motor under test (the authors' definition, module docstring)."""
    home = (df[col("target pos", stand.dut)] == stand.home).to_numpy()
    pos = df[col("pos", stand.dut)].to_numpy(float)
    rel = relaxed(df, stand)
    groups = {(m, s): [] for m in stand.pullers for s in ("loaded", "unloaded")}
    for a, b in runs(home):
        if b - a < 10:
            continue
        for m in stand.pullers:
            for pa, pb in runs(pulling(df, m, stand)[a:b]):
                groups[m, "loaded"].append(pos[a + pa:a + pb])
                after = [(ra, rb) for ra, rb in runs(rel[a:b]) if ra > pb - 1]
                if after:
                    ra, rb = after[0]
                    groups[m, "unloaded"].append(pos[a + ra:a + rb])
    out = {}
    for state in ("loaded", "unloaded"):
        means = [np.concatenate(groups[m, state]).mean() for m in stand.pullers if groups[m, state]]
        out[state] = float(abs(means[0] - means[1])) if len(means) == 2 else float("nan")
    return out


def settled_unpushed(df: pd.DataFrame, stand: Stand = Stand()) -> list[Level]:
    """The settled position of the motor under test at every target level, from the relaxed
    samples right after the target step (before any pull), the last 3 of the first relaxed stretch
    that has stopped moving; the standard error of a reading to the nearest count, 1/sqrt(12)."""
    target = df[col("target pos", stand.dut)].to_numpy(float) - stand.home
    pos = df[col("pos", stand.dut)].to_numpy(float) - stand.home
    rel = relaxed(df, stand)
    levels = []
    for a, b in _level_runs(target):
        for ra, rb in runs(rel[a:b]):
            tail = pos[a + ra:a + rb][-3:]
            if rb - ra >= 4 and np.ptp(tail) == 0:
                levels.append(Level("log", len(levels), float(target[a]), float(tail.mean()), 1 / np.sqrt(12), 3))
                break
    return levels


def _level_runs(target: np.ndarray) -> list[tuple[int, int]]:
    change = np.flatnonzero(np.diff(target) != 0) + 1
    bounds = np.concatenate([[0], change, [target.size]])
    return list(zip(bounds[:-1], bounds[1:]))


def branch_gap(levels: list[Level]) -> float:
    """Mean settled position approached from above minus that approached from below, per target,
    averaged over the targets reached from both sides."""
    gaps = []
    for u in sorted({lv.u for lv in levels}):
        up = [lv.x for i, lv in enumerate(levels) if lv.u == u and i and levels[i - 1].u < u]
        down = [lv.x for i, lv in enumerate(levels) if lv.u == u and i and levels[i - 1].u > u]
        if up and down:
            gaps.append(np.mean(down) - np.mean(up))
    return float(np.mean(gaps)) if gaps else float("nan")


def main(paths) -> None:
    from sts3215_table import trust
    print("| log | authors: loaded play | authors: unloaded play | hwid: branch gap | hwid stage 1 on the unpushed levels: "
          "type, dead band d+ - d- [95 %] | chi2 / dof | trust |")
    print("|---|---|---|---|---|---|---|")
    for path in paths:
        df = pd.read_csv(path)
        for stand in stands(df):
            a = authors(df, stand)
            levels = settled_unpushed(df, stand)
            gap = branch_gap(levels)
            try:
                # a fit with no degree of freedom left to judge it (three targets: four distinct
                # points for four parameters) says so in the trust column; its chi-square measures
                # only the repeats' scatter (on hand-picked readings to the count, often exactly 0)
                res = HistoryFit(max_degree=3).fit(levels).result_
                ci = res.ci["dead_band"]
                band = (f"{res.dead_band:.2f} [{ci[0]:.2f}, {ci[1]:.2f}] counts "
                        f"({res.dead_band * DEGREES_PER_COUNT:.2f} deg)" if ci is not None else "undetermined")
                fit = f"{res.type}{' (type undetermined)' if 'type' in res.undetermined else ''}, {band}"
                chi, verdict = f"{res.chi2:.3g} / {res.dof}", trust(res)
            except HwidError as err:                    # too few levels in a log: say so in the row
                fit, chi, verdict = f"not identifiable ({err})", "-", "-"
            print(f"| {Path(path).name} (motor {stand.dut}, {len(levels)} levels) | "
                  f"{a['loaded']:.2f} counts ({a['loaded'] * DEGREES_PER_COUNT:.2f} deg) | "
                  f"{a['unloaded']:.2f} counts ({a['unloaded'] * DEGREES_PER_COUNT:.2f} deg) | {gap:.2f} counts | "
                  f"{fit} | {chi} | {verdict} |")


def held_out(path: Path, out: Path, split_s: float | None = None) -> None:
    """The whole-model fit on the log's first half (pushes included, as a user's first try would
    be), and ``hwid compare`` of that model on the second half, which it never saw."""
    from hwid.compare import compare
    from hwid.config import load
    from hwid.identify.whole import WholeModelFit
    from hwid.recorded import load_records
    from hwid.results import write_whole
    out.mkdir(parents=True, exist_ok=True)
    base = {"name": "sts3215-held-out", "sampling": {"dt": 0.1},
            "plant": {"kind": "recorded", "experiments": [{
                "file": str(path), "time": {"column": "timestamp"},
                "input": {"column": col("target pos", DUT), "offset": -HOME},
                "output": {"column": col("pos", DUT), "offset": -HOME}}]},
            "identification": {"whole": {"enabled": True, "max_order": 2}}}
    whole = load_records(load(_config(base, out / "whole_log.yaml")))
    split_s = split_s or 0.5 * whole[0].u.size * whole[0].dt
    fit_cfg = load(_config(base, out / "first_half.yaml", stop=split_s))
    res = WholeModelFit.from_config(fit_cfg).fit(load_records(fit_cfg)).result_
    write_whole(out / "model" / "whole.h5", fit_cfg, res)
    held = load(_config(base, out / "second_half.yaml", start=split_s))
    fitted = compare(out / "model", fit_cfg, out / "compare_fit", echo=lambda *a: None)
    result = compare(out / "model", held, out / "compare_held_out", echo=lambda *a: None)
    print(f"\n{Path(path).name}: whole-model fit on the first {split_s:.1f} s ({res.type}, dead band "
          f"{res.d_plus - res.d_minus:.2f} counts, G {res.structure}, h degree {len(res.h_coefficients) - 1}, "
          f"residual sigma {res.sigma:.3g} counts)")
    print("| part | fit % | RMS (counts) | whiteness p | input correlation p |")
    print("|---|---|---|---|---|")
    for name, r in (("first half (fitted)", fitted), ("second half (held out)", result)):
        print(f"| {name} | {r.fit_percent:.1f} | {r.rms:.2f} | {r.whiteness_p:.2g} | {r.input_correlation_p:.2g} |")


def _config(base: dict, path: Path, **window) -> Path:
    import copy

    import yaml
    data = copy.deepcopy(base)
    data["plant"]["experiments"][0].update(window)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


if __name__ == "__main__":
    logs = sys.argv[1:] or sorted(FOLDER.glob("motor_telemetry_*.csv"))
    main(logs)
    held_out(FOLDER / "motor_telemetry_single.csv", Path(__file__).resolve().parents[2] / "runs" / "sts3215_held_out")
