"""Stage 2 from a recorded plant's steady periodic stretches, whether or not the input went through
hwid's pre-compensator (paper Section 5, eqs. 17-28, with a distorted input).

Each periodic stretch that ``role: auto`` or ``role: sine`` found (:func:`hwid.recorded.periodic_segment`)
is one "sine" for :func:`hwid.identify.linear.estimate_response`: the record is cut from up to two
whole periods before the stretch (run through F_hat as the gear's history, left out of the fit as
lead-in) to its end. Stage 2 reads the input it was given: ``F_hat[u]`` over the cut, whose
fundamental ``V_1`` (amplitude and phase against ``sin(omega t)``) divides the output's, and whose
offset and other harmonics ``V_k`` reach ``w`` through ``G(j k omega)`` (from a first-pass rational
fit) in the harmonic model of eq. (20) -- exactly the correction the pre-compensated Backlash-Inverse
input needs. The stage 1 it takes is the history fit of the same records (:mod:`hwid.identify.history`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from hwid import HwidError, protocols
from hwid.identify.known import KnownNonlinear
from hwid.identify.linear import estimate_response
from hwid.identify.result import HistoryResult, LinearResult
from hwid.model import InputNonlinearity

#: Periods kept before a stretch as the gear's history (left out of the fit).
LEAD_PERIODS = 2
#: Passes of the distortion through a refitted G (:func:`hwid.identify.linear.estimate_response`).
PASSES = 3


@dataclass(frozen=True)
class HistoryStage1(KnownNonlinear):
    """A history fit as stage 2's stage 1: its normalised F and h_bar, the range of w its levels
    visited (``G(0) = 1``: w at a settled level is F's output there), and its covariance, which
    stage 2 propagates (:meth:`hwid.identify.linear.LinearEstimator.add_stage1_uncertainty`)."""

    cov: np.ndarray | None = None
    param_names: tuple = ()


def stage1_of(hist: HistoryResult) -> HistoryStage1:
    F = InputNonlinearity(hist.type, 1.0, hist.slope_down, hist.d_plus, hist.d_minus)
    us = np.array([lv.u for lv in hist.levels], float)
    vs = np.concatenate([np.atleast_1d(F.ascending(us)), np.atleast_1d(F.descending(us))])
    cov = np.asarray(hist.cov, float) if len(hist.cov) else None
    return HistoryStage1(F, tuple(hist.h_coefficients), (float(vs.min()), float(vs.max())), cov,
                         tuple(hist.param_names))


def periodic_pieces(records) -> tuple[list, list]:
    """``(records, sines)``: each periodic stretch cut with its lead-in, and the
    :class:`hwid.protocols.Sine` it is read against (amplitude: the input's fundamental)."""
    from dataclasses import replace
    pieces, sines = [], []
    for r in records:
        for seg in json.loads(r.attrs.get("segments", "[]") or "[]"):
            if seg.get("kind") != "periodic":
                continue
            omega, start, stop = float(seg["omega"]), int(seg["start"]), int(seg["stop"])
            n_period = 2 * np.pi / omega / r.dt
            lead = int(min(LEAD_PERIODS, np.floor(start / n_period)))
            a = int(round(start - lead * n_period))
            periods = int(np.floor((stop - a) / n_period + 1e-9)) - lead
            if periods < 2:
                continue
            u = np.asarray(r.u[a:stop], float)
            t = np.arange(u.size) * r.dt
            basis = np.column_stack([np.ones_like(t), np.sin(omega * t), np.cos(omega * t)])
            coef = np.linalg.lstsq(basis, u, rcond=None)[0]
            amplitude = float(np.hypot(coef[1], coef[2])) or 1.0
            sine = protocols.sine(amplitude, omega, periods, lead, r.dt, name=f"{r.name}_w{omega:.4g}")
            pieces.append(replace(r, name=sine.name, u=u, y=np.asarray(r.y[a:stop], float), v=None, w=None, x=None,
                                  z=None, attrs={**r.attrs, "omega": omega, "amplitude": amplitude,
                                                 "periods": periods, "lead_in_periods": lead,
                                                 "precompensator": "none (recorded)", "source_start": a}))
            sines.append(sine)
    return pieces, sines


def identify_periodic(cfg, records, hist: HistoryResult) -> tuple[LinearResult, list]:
    """Stage 2 on every steady periodic stretch of ``records`` with the stage 1 of ``hist``;
    returns the result and the cut records."""
    pieces, sines = periodic_pieces(records)
    if not pieces:
        raise HwidError("stage 2 needs a steady periodic stretch of at least two whole periods in the records "
                        "(role: auto or sine finds them); none was found")
    order = np.argsort([s.omega for s in sines])
    pieces, sines = [pieces[i] for i in order], [sines[i] for i in order]
    return estimate_response(pieces, sines, stage1_of(hist), cfg, precompensator="none", passes=PASSES), pieces
