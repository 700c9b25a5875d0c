"""Every catalogue effect fitted by one :class:`hwid.diagnose.rank.EffectFitter`, the fits side by
side in forked workers, the candidates ranked (:func:`fit_all`).
"""
from __future__ import annotations

from hwid.diagnose.verdict import Candidate, rank
from hwid.threads import forked_map

#: The effects' fits, longest first (seconds on five identified diagnoses of labelled development
#: rigs: curved borders 2.8-5.4, sensor lag 2.5-5.0, resonance 1.8-4.8, rate limit 1.1-3.1, the
#: others 0.5-2.9, drift 0.02): the order the workers take them in. An effect not listed goes first.
LONGEST_FIRST = ("curved_borders", "sensor_lag", "resonance", "rate_limit", "input_deadzone", "input_saturation",
                 "sensor_saturation", "time_delay", "drift")


def fit_all(fitter, effects: dict, echo=None) -> list[Candidate]:
    """Fit every effect; return the candidates ranked (explained fraction, then score).

    The effects' fits are independent (each starts from the same baseline and leaves the fitter as
    it found it): on several cores they run in forked workers, one effect at a time each, the
    longest first (:func:`hwid.threads.forked_map`, :data:`LONGEST_FIRST`), which halves a
    diagnosis's analysis on the 2-core machine."""
    names = list(effects)
    out = forked_map(lambda name: fitter.fit(effects[name]), names,
                     cost=lambda name: -LONGEST_FIRST.index(name) if name in LONGEST_FIRST else 1)
    if echo:
        for name, c in zip(names, out):
            echo(f"  {name:18s} explained {c.explained_fraction:5.2f}  gap after {c.gap_after:.4g}  "
                 f"score {c.score:.4g}  {c.params}")
    return rank(out)
