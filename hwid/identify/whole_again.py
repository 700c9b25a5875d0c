"""The whole fit again from a model that misses its own records (:mod:`hwid.identify.path`).

A model the identification reached by another route (the two stages, or the whole fit with the
input's slew rate from the start) can miss its own records where the route left something out of
the fit (h read on the staircases' range and extrapolated where the sines drive G's output beyond
it; a slew rate standing in for a G structure the rate's search did not reach). The whole fit
started from that model descends to the records themselves; :func:`fits_from` runs it.
"""
from __future__ import annotations

import numpy as np

from hwid import HwidError
from hwid.identify.whole import WholeModelFit
from hwid.model import HWModel


def fits_from(cfg, start: HWModel, records, judge) -> tuple:
    """The whole fit on ``records`` from the model ``start`` (no actuator), judged by ``judge`` (a
    :class:`~hwid.identify.result.WholeResult` to an :class:`hwid.adequacy.Adequacy`): first from
    its F, G and h (G's structure, h_bar's neighbouring degrees), then, where that is not adequate,
    from its borders with every G structure and degree (staged, :meth:`WholeModelFit.fit` with
    ``borders``), then from the border grid with both types of F (the start's type can be wrong: a
    folded h read from the levels made stage 1 a Backlash-Inverse without play for a Backlash, and
    both fits of that type stopped at 9.4x the noise). ``(adequacy, fitter)`` of the one nearer
    the records; None where no attempt could be fitted (each one that cannot -- too few records
    for its start, a degenerate design -- is passed over: the model then stays the start)."""
    tried = []
    for fit in (lambda: WholeModelFit.from_config(cfg).fit(records, start=start),
                lambda: WholeModelFit.from_config(cfg, staged=True).fit(records, borders=start.input),
                lambda: WholeModelFit.from_config(cfg, staged=True).fit(records)):
        try:
            done = fit()
        except (HwidError, ValueError, np.linalg.LinAlgError):
            continue
        tried.append((judge(done.result_), done))
        if tried[-1][0].verdict == "adequate":
            break
    if not tried:
        return None
    return min(tried, key=lambda t: t[0].rms_fit if np.isfinite(t[0].rms_fit) else np.inf)
