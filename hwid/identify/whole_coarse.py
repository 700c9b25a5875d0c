"""Long records fitted whole, coarse first: the descent from each start runs on every ``k``-th
sample of the records, and the best few fits are polished on every sample from where they ended.

The whole fit's cost is its simulations', each as long as the records. Where the input did not
follow (:func:`hwid.identify.whole_rate.fit_rate_first`), every type and structure descends from
several starts; on the paper's protocol (2,900 rig-s, 58,000 samples) that took a judged rig's
diagnosis to 219-229 s. Descended on a few thousand samples, each start reaches the valley of the
fit on all of them, where a short polish on every sample ends (:data:`POLISH_NFEV`); the fits the
coarse records rank below the best :data:`POLISH_BEST` are not polished (the polish moves a fit
little, and the selection takes the best).

The thinned records hold each interval's middle input sample (:func:`thinned`): held over the
interval, it neither leads nor lags the one the plant received; a jump moves by at most half an
interval, and the polish on every sample puts it back. ``k`` is bounded by the input's own pace
(:func:`thinning`): an interval is at most a tenth of a radian of its RMS frequency.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from hwid.identify.defaults import COARSE_SAMPLES, POLISH_BEST, POLISH_NFEV, READ_ALL
from hwid.identify.whole_problem import table_row
from hwid.plant import Record


def thinning(records) -> int:
    """How many samples of ``records`` the coarse descent holds as one: 1 (none) for at most
    :data:`READ_ALL` samples; else enough for about :data:`COARSE_SAMPLES`, but no interval longer
    than a tenth of a radian of the input's RMS frequency ``sqrt(mean(du/dt ^ 2) / var(u))`` over
    all the records (a staircase's jumps and a sine's swings both count)."""
    n = sum(int(np.size(r.u)) for r in records)
    if n <= READ_ALL:
        return 1
    du2 = sum(float(np.sum(np.diff(np.asarray(r.u, float)) ** 2) / r.dt ** 2) for r in records)
    u = np.concatenate([np.asarray(r.u, float) for r in records])
    var = float(np.var(u))
    dt = min(float(r.dt) for r in records)
    if not var > 0 or not du2 > 0:
        return int(np.ceil(n / COARSE_SAMPLES))
    omega = float(np.sqrt(du2 / max(n - len(records), 1) / var))
    return int(max(1, min(np.ceil(n / COARSE_SAMPLES), np.floor(0.1 / (omega * dt)))))


def thinned(record, k: int):
    """``record`` at every ``k``-th output sample, each interval's input its middle sample (held
    over the interval, it neither leads nor lags the input the plant received); a ``burn_in``
    (samples left out of the cost) shrinks with it."""
    if k <= 1:
        return record
    u, y = np.asarray(record.u, float), np.asarray(record.y, float)
    mid = np.minimum(np.arange(0, u.size, k) + k // 2, u.size - 1)
    attrs = dict(record.attrs)
    if "burn_in" in attrs:
        attrs["burn_in"] = int(np.ceil(int(attrs["burn_in"]) / k))
    return Record(record.name, record.dt * k, u[mid], y[::k], attrs=attrs)


def coarse_first(probs, starts, max_nfev: int, descend, pick=None) -> tuple[list, list] | None:
    """``probs`` fitted from ``starts`` by ``descend(probs, starts, max_nfev)`` (the whole fit's
    descent), coarse first where the records are long (:func:`thinning`): ``(problems, fits)``, or
    None where they are read whole at once. Of the coarse fits, those ``pick(coarse_problems,
    fits)`` names (their indices; default all) are polished on every sample, at most
    :data:`POLISH_BEST` of them, best first by the selection's criterion on the coarse records:
    the others are not selected whatever the polish does, which moves a fit by little."""
    k = thinning(probs[0].records)
    if k <= 1:
        return None
    coarse = [dataclasses.replace(p, records=[thinned(r, k) for r in p.records]) for p in probs]
    fits = descend(coarse, starts, max_nfev)
    keep = list(range(len(probs))) if pick is None else list(pick(coarse, fits))
    keep = sorted(keep, key=lambda i: table_row(coarse[i], fits[i][1])["aic"])[:POLISH_BEST]
    probs = [probs[i] for i in keep]
    return probs, descend(probs, [fits[i][0] for i in keep], POLISH_NFEV)
