"""The paper's published numbers (Section 6), in one place.

Shown beside hwid's own estimates by ``experiments/paper/`` and by ``hwid report`` when the config
is the paper's (:data:`CONFIG_NAME`). Nothing here is used to compute an estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

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
