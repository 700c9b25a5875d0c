"""The paper's published numbers (Section 6), in one place.

Shown beside hwid's own estimates by ``experiments/paper/`` and by ``hwid report`` when the config
is the paper's (:data:`CONFIG_NAME`). Nothing here is used to compute an estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from hwid import protocols
from hwid.model import from_config

#: ``name:`` of ``configs/paper.yaml``; a run with this name gets the paper's columns in its report.
CONFIG_NAME = "paper-section6"


@dataclass(frozen=True)
class Table1Row:
    """One row of Table 1 (Section 6.1): level ``j`` (1-based over both staircases), ``U_j``, the
    true ``X_j(M)`` and the paper's estimate ``X_hat_j(M)`` (eq. 9 with M = 100)."""

    j: int
    U: float
    X: float
    X_hat: float


@dataclass(frozen=True)
class Table2Row:
    """One row of Table 2 (Section 6.2): ``omega_i`` (rad/s), the true phase ``phi`` and gain
    ``|G|`` of eq. (30b), and the paper's estimates (eqs. 26a-e with U = 1, N = 50)."""

    omega: float
    phi: float
    phi_hat: float
    gain: float
    gain_hat: float


TABLE1 = (
    Table1Row(5, 0.2, -0.075, -0.076), Table1Row(6, 0.4, -0.047, -0.048), Table1Row(7, 0.6, 0.047, 0.045),
    Table1Row(8, 0.8, 0.075, 0.074), Table1Row(9, 1.0, 0.03, 0.028), Table1Row(10, 1.2, 0.27, 0.26),
    Table1Row(16, 0.0, 0.03, 0.031), Table1Row(17, -0.3, 0.075, 0.076), Table1Row(18, -0.6, -0.047, -0.046),
    Table1Row(19, -1.0, -0.03, -0.029), Table1Row(20, -1.2, -0.27, -0.265), Table1Row(21, -1.4, -1.78, -1.775),
)

#: The paper's border estimates (Section 6.1): d_hat^+(M), S_hat^d(M), d_hat^-(M).
BORDERS = {"d_plus": 0.503, "slope_down": 1.01, "d_minus": -0.49}

TABLE2 = (
    Table2Row(0.01, 0.07, 0.065, 0.998, 1.01), Table2Row(0.02, 0.14, 0.147, 0.99, 0.97),
    Table2Row(0.05, 0.34, 0.33, 0.96, 0.95), Table2Row(0.1, 0.66, 0.68, 0.87, 0.89),
    Table2Row(0.2, 1.16, 1.19, 0.65, 0.68),
)


def table1_row(j: int) -> Table1Row | None:
    """Table 1's row for level ``j``, or None where the paper gives none."""
    return next((r for r in TABLE1 if r.j == j), None)


def table2_row(omega: float, rtol: float = 1e-9) -> Table2Row | None:
    """Table 2's row at ``omega`` (rad/s), or None where the paper gives none."""
    return next((r for r in TABLE2 if abs(r.omega - omega) <= rtol * max(abs(omega), 1.0)), None)


# ------------------------------------------------------------------------- ours beside theirs

def table1_rows(cfg, result) -> dict:
    """Table 1 side by side for a simulated config: for every level j (1-based over both staircases)
    ``U_j``, the paper's ``X_j`` and ``X_hat_j(M)`` where the paper gives them, the true ``X_j`` of the
    normalised plant, ours and its interval; and the borders (paper, truth, ours, interval)."""
    truth = from_config(cfg.plant).normalised()
    up, down = protocols.staircases(cfg)
    Xt = np.concatenate([truth.staircase_steady(up.lead_in, up.levels),
                         truth.staircase_steady(down.lead_in, down.levels)])
    published = {r.j: (r.X, r.X_hat) for r in TABLE1}
    # simultaneous (Sidak) 95 % intervals over all levels of the table: each pointwise interval
    # widened from z_{0.975} to z_{(1 + 0.95^{1/n})/2}, so all n hold the truth together w.p. 95 %
    n = len(result.X_hat)
    widen = special.ndtri(0.5 + 0.5 * 0.95 ** (1.0 / n)) / special.ndtri(0.975)
    rows = []
    for j, (u, x, ci, xt) in enumerate(zip(result.levels, result.X_hat, result.ci["X_hat"], Xt), start=1):
        px, pxh = published.get(j, (None, None))
        half = 0.5 * (ci[1] - ci[0]) * widen
        cj = (x - half, x + half)
        rows.append({"j": j, "U": u, "paper_X": px, "paper_X_hat": pxh, "true_X": float(xt), "X_hat": x,
                     "ci": tuple(ci), "inside": bool(ci[0] <= xt <= ci[1]),
                     "ci_joint": cj, "inside_joint": bool(cj[0] <= xt <= cj[1])})
    true_b = {"d_plus": truth.input.d_plus, "slope_down": truth.input.slope_down, "d_minus": truth.input.d_minus}
    borders = []
    for k in ("d_plus", "slope_down", "d_minus"):
        ci = result.ci[k]
        borders.append({"name": k, "paper": BORDERS[k], "true": float(true_b[k]),
                        "ours": float(getattr(result, k)), "ci": None if ci is None else tuple(ci),
                        "inside": ci is not None and bool(ci[0] <= true_b[k] <= ci[1])})
    return {"rows": rows, "borders": borders}
