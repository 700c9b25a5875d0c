"""The split of recorded experiments into a fit part and a held-out part, decided before any model
is known: :func:`plan` (by experiment, or by interleaved time blocks) and :func:`fit_pieces` (the
fit part as records of its own). Both ``hwid run`` on a recorded plant and ``hwid diagnose`` from
logs identify the model on the fit part (:func:`hwid.identify.path.identify`) and hold the rest
out to judge it.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from hwid import HwidError
from hwid.masks import runs
from hwid.recorded import level_segments

#: Fewest scored samples a record needs to take part in the split.
MIN_SCORED = 50

#: Blocks a single record is cut into (odd ones to validation).
N_BLOCKS = 8


def _kind(record) -> str:
    """What a record holds, from :func:`hwid.recorded.level_segments`: ``levels`` (held at least
    half the time), ``moving`` otherwise."""
    u = np.asarray(record.u, float)
    held = sum(seg["stop"] - seg["start"] for seg in level_segments(u))
    return "levels" if held >= 0.5 * u.size else "moving"


def _covers(parts, share: float = 0.05) -> bool:
    """Whether the validation records' input reaches both ends of the fit records' (within
    ``share`` of its range): effects that live at the extremes (a clip) must be seen by both."""
    fit = np.concatenate([r.u for r, role, _ in parts if role == "fit"])
    val = np.concatenate([r.u for r, role, _ in parts if role == "validation"])
    tol = share * max(float(np.ptp(fit)), 1e-12)
    return bool(val.min() <= fit.min() + tol and val.max() >= fit.max() - tol)


def plan(records) -> tuple[list[tuple], str]:
    """Which samples fit and which validate, decided before any model is known (so identifying
    the model on the fit part never sees the validation part): ``([(record, role, samples), ...],
    how)``.

    By experiment where every kind of record (held levels, or moving input) comes at least twice
    and the validation records reach both ends of the fit records' input range: every other record
    of each kind to validation, in recorded order. Otherwise by interleaved
    blocks: each record cut in :data:`N_BLOCKS` equal blocks (fewer for a short one, none under
    ``2 MIN_SCORED`` samples), the odd ones to validation, the record kept whole so its history
    carries across the blocks. Validation by whole experiments of kinds the fit never saw would
    be blind to what only the fit's kind excites (a rate limit shows in steps, not in slow sines)."""
    kinds = [_kind(r) for r in records]
    if len(records) >= 2 and all(kinds.count(k) >= 2 for k in set(kinds)):
        seen: dict[str, int] = {}
        out = []
        for r, k in zip(records, kinds):
            out.append((r, "fit" if seen.get(k, 0) % 2 == 0 else "validation", np.ones(r.u.size, bool)))
            seen[k] = seen.get(k, 0) + 1
        if _covers(out):
            return out, "experiments"
    out = []
    for r in records:
        n_blocks = min(N_BLOCKS, r.u.size // MIN_SCORED) // 2 * 2
        if n_blocks < 2:
            continue
        block = (np.arange(r.u.size) * n_blocks) // r.u.size
        out += [(r, "fit", block % 2 == 0), (r, "validation", block % 2 == 1)]
    if not out:
        raise HwidError(f"diagnose: every record is shorter than {2 * MIN_SCORED} samples: too short to split into fit "
                        "and validation blocks; record longer")
    return out, "blocks"


def fit_pieces(parts) -> list:
    """The records the model is identified from: the fit records, or a split record's fit blocks
    as records of their own (``name:fit0``, ``name:fit1``, ...)."""
    return _pieces(parts, "fit", "fit")


def held_out_pieces(parts) -> list:
    """The held-out records as :func:`fit_pieces` gives the fit ones: the validation records, or a
    split record's validation blocks as records of their own (``name:held0``, ...)."""
    return _pieces(parts, "validation", "held")


def _pieces(parts, role: str, tag: str) -> list:
    out = []
    for r, part_role, samples in parts:
        if part_role != role:
            continue
        if samples.all():
            out.append(r)
            continue
        for k, (a, b) in enumerate(runs(samples)):
            out.append(replace(r, name=f"{r.name}:{tag}{k}", u=r.u[a:b], y=r.y[a:b], attrs=dict(r.attrs)))
    return out
