"""Runs of True in a boolean sample mask: the one helper the adequacy, the recorded-log reader, the
rails and the record splitter share."""
from __future__ import annotations

import numpy as np


def runs(mask) -> list[tuple[int, int]]:
    """``[start, stop)`` of each run of True in ``mask``, in order."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, bool).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def run_lengths(mask) -> np.ndarray:
    """The length of each run of True in ``mask``, in order."""
    return np.array([b - a for a, b in runs(mask)], int)
