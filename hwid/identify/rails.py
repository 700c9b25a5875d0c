"""Where the measured output rests on its sensor's rail: runs of one exact value at the records'
smallest or largest reading.

A sensor past the end of its range reports the end of its range: an ADC its first or last code, a
clipping amplifier its supply. Its samples there repeat one value exactly, noise and all gone, while
everywhere else a noisy sensor almost never reads the same value twice. That is evidence
no model is needed for, and it matters twice over:

* the identification's sines must not rest on a rail (stage 2 reads G from the output's harmonics,
  and a clipped output's harmonics are not those of ``h(G w)``): the paper's plant behind a
  sensor that clipped its amplitude-1 sines was identified with a right-half-plane zero in G and a
  degree-6 h, which no effect's refit could repair (:func:`hwid.diagnose.sim_side.identified_model`
  runs them again smaller);
* a log whose clipped stretch lies where the model's state is unknown (its opening) shows no gap
  on the validation part, yet the rig clipped: the diagnosis names ``sensor_saturation`` from the
  rail where the gap test finds nothing (:func:`hwid.diagnose.conclude.conclude`).

A quantised sensor (an encoder's counts) repeats values everywhere; there a repeat says nothing and
no rail is reported (:data:`MAX_REPEATS_ELSEWHERE`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwid.masks import run_lengths

#: the shortest run of one exact value that counts as resting on a rail (samples)
MIN_RUN = 10

#: the fewest samples on a rail, over all records, for the rail to be reported
MIN_SAMPLES = 20

#: the fewest readings away from the rails (and no fewer than on them) that tell the sensor's noise
MIN_REST = 200

#: above this share of repeated readings away from the rails (any reading met before) the sensor is
#: quantised or noise-free, and a repeat is no evidence of a rail: an encoder at rest reads one
#: count for as long as it rests, at the end of a move as anywhere else
MAX_REPEATS_ELSEWHERE = 0.01


@dataclass(frozen=True)
class Rail:
    """One end of the sensor's range the output rested on."""

    side: str          # "low" or "high"
    value: float       # the reading on the rail
    samples: int       # samples on it, in runs of at least MIN_RUN
    runs: int
    records: tuple     # names of the records that reach it

    def to_dict(self) -> dict:
        return {"side": self.side, "value": self.value, "samples": self.samples, "runs": self.runs,
                "records": list(self.records)}


def find_rails(ys, names=None) -> list[Rail]:
    """The rails the outputs ``ys`` (one array per record; ``names`` for the report) rest on, low
    first; empty where none is reached or the sensor repeats readings away from its extremes."""
    ys = [np.asarray(y, float) for y in ys if np.size(y)]
    if not ys:
        return []
    names = list(names) if names is not None else [f"record {i}" for i in range(len(ys))]
    finite = [y[np.isfinite(y)] for y in ys]
    if not any(y.size for y in finite):
        return []
    lo = min(float(y.min()) for y in finite if y.size)
    hi = max(float(y.max()) for y in finite if y.size)
    if not hi > lo:
        return []
    out, on_rail = [], [np.zeros(y.size, bool) for y in ys]
    for side, value in (("low", lo), ("high", hi)):
        samples, runs, where = 0, 0, []
        for k, y in enumerate(ys):
            at = y == value
            lengths = run_lengths(at)
            long = lengths[lengths >= MIN_RUN]
            if long.size:
                samples, runs = samples + int(long.sum()), runs + int(long.size)
                where.append(names[k])
            on_rail[k] |= at
        if samples >= MIN_SAMPLES:
            out.append(Rail(side, value, samples, runs, tuple(where)))
    if not out:
        return []
    rest = np.concatenate([y[~r] for y, r in zip(ys, on_rail)])
    rest = rest[np.isfinite(rest)]
    if rest.size < max(MIN_REST, sum(r.samples for r in out)):
        return []      # a signal that mostly sits still says nothing of its sensor's noise
    if rest.size - np.unique(rest).size > MAX_REPEATS_ELSEWHERE * rest.size:
        return []
    return out


def describe(rails: list[Rail], dt: float) -> str:
    """One line for the log and the verdict's ``why``."""
    return "; ".join(f"the output rests on its {r.side} rail {r.value:.6g} for {r.samples} samples "
                     f"({r.samples * dt:.3g} s, {r.runs} run{'s' if r.runs != 1 else ''})" for r in rails)


def rail_values(records) -> tuple:
    """The readings of the rails the records' outputs rest on (:func:`find_rails`), for the
    adequacy to leave out (:func:`hwid.adequacy.assess`'s ``off_rails``)."""
    return tuple(r.value for r in find_rails([r.y for r in records if getattr(r, "y", None) is not None]))
