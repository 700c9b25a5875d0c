"""Reproduce the paper's Table 1 and its border estimates (Section 6.1) with ``configs/paper.yaml``.

    .venv/bin/python experiments/paper/table1.py [--seed N] [--method nls|paper] [--write]

Prints, for every level of both staircases, U_j, the paper's X_j and X_hat_j(M) (where Table 1 gives
them), the true X_j of the normalised plant, and ours with its 95 % interval; then d^+, S^d, d^- as the
paper gives them (0.503, 1.01, -0.49), the truth and ours. The rows come from
:func:`hwid.paper.table1_rows`, which tests and the report reuse. ``--write`` replaces the Table 1
fragment of docs/validation/paper.md (``docs/validation/generated/paper_table1.md``).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run(seed: int | None = None, method: str | None = None):
    """Run stage 1 on the paper's plant; return ``(cfg, result, table)``."""
    from hwid import config
    from hwid.identify.nonlinear import identify_nonlinear
    from hwid.paper import table1_rows
    cfg = config.load(ROOT / "configs" / "paper.yaml")
    over = {}
    if seed is not None:
        over["seed"] = seed
    if method is not None:
        over["identification.nonlinear.method"] = method
    if over:
        cfg = config.with_overrides(cfg, over)
    res, _ = identify_nonlinear(cfg)
    return cfg, res, table1_rows(cfg, res)


def _f(x, fmt="{:+.4f}"):
    return "" if x is None else fmt.format(x)


def page(cfg, res, tab) -> str:
    """The docs page's Table 1: what stage 1 chose, the borders beside the paper's and the truth, and
    how the levels' steady outputs sit against their intervals."""
    sym = {"d_plus": "d^+", "slope_down": "S^d", "d_minus": "d^-"}
    lines = [f"Seed {cfg.seed}. j_a = {res.flat_up}, j_d = {res.flat_down}, the degree {res.degree} and the type "
             f"({res.type}) are all chosen from the data.", "",
             f"| | paper | truth | hwid ({res.method}) | 95 % interval |", "|---|---|---|---|---|"]
    for b in tab["borders"]:
        lines.append(f"| {sym[b['name']]} | {b['paper']:g} | {b['true']:g} | {b['ours']:.5f} | "
                     f"[{b['ci'][0]:.5f}, {b['ci'][1]:.5f}] |")
    rows = tab["rows"]
    n = len(rows)
    joint = sum(r["inside_joint"] for r in rows)
    point = sum(not r["inside"] for r in rows)
    worst = max(abs(r["X_hat"] - r["true_X"]) for r in rows)
    paper = [abs(r["paper_X_hat"] - r["true_X"]) for r in rows if r["paper_X_hat"] is not None]
    lines += ["", f"{joint} of {n} levels' steady outputs X̂_j lie within their simultaneous (Šidák) 95 % intervals "
                  f"of the truth; {point} of {n} lie outside their pointwise 95 % intervals (about {0.05 * n:.0f} "
                  f"expected by chance). Every X̂_j is within {worst:.1e} of the truth"
                  + (f" (the paper's own X̂_j are off by up to {max(paper):.2g})." if paper else ".")]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=None, help="override the config's seed")
    ap.add_argument("--method", choices=("nls", "paper"), default=None)
    ap.add_argument("--write", action="store_true", help="write the docs page's fragment (docs/validation/generated/)")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    cfg, res, tab = run(a.seed, a.method)
    el = time.perf_counter() - t0
    print(f"Table 1 ({cfg.name}, seed {cfg.seed}, method {res.method}; type {res.type}, degree {res.degree}, "
          f"j_a = {res.flat_up}, j_d = {res.flat_down}; {el:.1f} s)")
    print(f"{'j':>3} {'U_j':>6} | {'paper X_j':>9} {'paper X^_j':>10} | {'true X_j':>9} | {'ours X^_j':>9}"
          f"  {'95 % interval':>21}  {'(ours-true)/se':>14}")
    out = 0
    for r, se in zip(tab["rows"], res.X_hat_se):
        z = (r["X_hat"] - r["true_X"]) / se
        out += not r["inside"]
        print(f"{r['j']:>3} {r['U']:+6.2f} | {_f(r['paper_X'], '{:+.3f}'):>9} {_f(r['paper_X_hat'], '{:+.3f}'):>10} | "
              f"{r['true_X']:+9.5f} | {r['X_hat']:+9.5f}  [{r['ci'][0]:+9.5f}, {r['ci'][1]:+9.5f}]  {z:+14.2f}"
              f"{'' if r['inside'] else '  <- outside'}")
    n_joint = sum(not r["inside_joint"] for r in tab["rows"])
    print(f"{out} of {len(tab['rows'])} levels outside their pointwise 95 % interval (about 1 expected); "
          f"{n_joint} outside the simultaneous 95 % intervals (Sidak, all {len(tab['rows'])} levels jointly)")
    ok_levels = n_joint == 0
    print()
    print(f"{'':>11} {'paper':>7} {'true':>8} {'ours':>9}  {'95 % interval':>21}  {'|ours-true|':>11}  bound")
    bounds = {"d_plus": 0.01, "slope_down": 0.02, "d_minus": 0.01}
    ok = True
    for b in tab["borders"]:
        err = abs(b["ours"] - b["true"])
        ok &= err <= bounds[b["name"]] and b["inside"]
        print(f"{b['name']:>11} {b['paper']:+7.3f} {b['true']:+8.4f} {b['ours']:+9.5f}  "
              f"[{b['ci'][0]:+9.5f}, {b['ci'][1]:+9.5f}]  {err:11.2e}  {bounds[b['name']]:g}"
              f"{'' if b['inside'] else '  <- truth outside interval'}")
    for w in res.warnings:
        print(f"note: {w}")
    if a.write:
        sys.path.insert(0, str(ROOT / "docs"))
        from fragment import write
        print(f"wrote {write('paper_table1', page(cfg, res, tab), 'experiments/paper/table1.py')}")
    return 0 if ok and ok_levels else 1


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
