"""The diagnosis's model checked on its own records before its gap is read
(:func:`hwid.adequacy.assess`): an identified model on the records it was identified from (from the
starts the identification estimated, where it did), a given model on the validation records. A
model that misses its own records by more than noise cannot make the diagnosis say that the gap is
noise: the verdict is then ``unexplained``, never ``none``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from hwid import adequacy
from hwid.diagnose import gap
from hwid.diagnose.context import Context
from hwid.identify.rails import rail_values


def adequacy_where(ctx: Context) -> str:
    """Which records :func:`model_adequacy` judged the model on, in words."""
    if ctx.adequacy_on:
        return ctx.adequacy_on
    if ctx.identified and ctx.origin.get("records"):
        if ctx.origin.get("baseline") == "actuator taken out":
            # the diagnosis's baseline, not the model as identified (JSON ``model.adequacy``)
            return "its own records (those it was identified from), with its actuator taken out"
        return "its own records (those it was identified from)"
    return "the validation records"


def model_adequacy(ctx: Context) -> adequacy.Adequacy | None:
    """The model's adequacy, its noise floor estimated from the records judged alone
    (:func:`hwid.adequacy.estimate_floor`): an identified model's free run on its identification
    records (from the starts the identification estimated, where it did; off the sensor's rails,
    as the identification judged it); a given model's
    predictions on the validation records as the diagnosis simulates them (each from the input
    the plant had before it). None where there are no records."""
    if ctx.identified and ctx.origin.get("records"):
        records = [r for r in ctx.origin["records"] if getattr(r, "y", None) is not None]
        return adequacy.assess(ctx.sim_model, records, starts=ctx.origin.get("starts"),
                               off_rails=rail_values(records)) if records else None
    val = ctx.val
    records = [val.records[i] for i in val.val_idx]
    if not records:
        return None
    scored, own = [], []
    for r, x, m in zip(records, val.sim_val.x, val.m_val):
        y, u = np.asarray(r.y, float), np.asarray(r.u, float)
        scored.append((y[m] - np.asarray(x, float)[m], u[m], y[m]))
        pre = int((getattr(r, "attrs", None) or {}).get("pre", 0) or 0)   # a start estimated before the log
        own.append(replace(r, u=u[pre:], y=y[pre:]))
    step = adequacy.lag_step(val.design.dt, val.design.settle_s)
    return adequacy.judge(scored, adequacy.estimate_floor(own), step=step, label="the validation records")


def fails_own_records(ctx: Context, min_ratio: float) -> adequacy.Adequacy | None:
    """The model's adequacy where it is a misfit by more than the diagnosis allows a model's own
    error (mean-square ratio ``min_ratio``, the gap test's: 1.25 for an identified model, 1.1 for a
    given one); else None."""
    ad = ctx.model_adequacy
    if ad is None or not ad.misfit or not ad.ratio ** 2 > min_ratio:
        return None
    return ad


def not_none_from_a_misfit(ctx: Context, verdict, why: str, min_ratio: float) -> tuple[object, str]:
    """``(verdict, why)``, with ``none`` turned into ``unexplained`` where the model fails its own
    records (:func:`fails_own_records`): what the model misses there is not noise; and where the
    only floor is the model's own residual's (no repeat, hold or smooth stretch in the data: the
    data-alone floor undetermined), which cannot tell noise from what the model misses."""
    if verdict == "none" and ctx.floor_from_model and not (ctx.model_adequacy is not None
                                                           and ctx.model_adequacy.floor.determined):
        why = (f"the records hold no repeat, settled hold or smooth stretch to estimate the noise from: the "
               f"diagnosis's floor {ctx.floor.sigma:.4g} is the high-frequency part of the model's own residual, "
               "which holds whatever the model misses from one sample to the next, and a gap within it is no sign "
               "that the plant is the model: unexplained instead of none")
        ctx.echo(why)
        return "unexplained", why
    ad = fails_own_records(ctx, min_ratio)
    if verdict != "none" or ad is None:
        return verdict, why
    rms = ad.rms_fit if ad.rms_held_out is None else max(ad.rms_fit, ad.rms_held_out)
    why = (f"the model is not adequate on {adequacy_where(ctx)}: RMS {rms:.4g} = {ad.ratio:.3g} x the floor "
           f"{ad.floor.sigma:.4g} ({ad.floor.source}, from the data alone); a gap within the diagnosis's noise floor "
           f"{ctx.floor.sigma:.4g} is then no sign that the plant is the model: unexplained instead of none")
    ctx.echo(why)
    return "unexplained", why


def describe_misfit(ctx: Context) -> str:
    """One line for a model that is a misfit on its records: by how much, against which floor."""
    ad = ctx.model_adequacy
    rms = ad.rms_fit if ad.rms_held_out is None else max(ad.rms_fit, ad.rms_held_out)
    return (f"the model is not adequate on {adequacy_where(ctx)}: RMS {rms:.4g} = {ad.ratio:.3g} x the floor "
            f"{ad.floor.sigma:.4g} ({ad.floor.source}, from the data alone): {ad.reason}")


def adequacy_tail(ctx: Context) -> str:
    """The verdict line's tail: the model's own fit on its records."""
    ad = ctx.model_adequacy
    if ad is None:
        return ""
    if not ad.floor.determined:
        return f"; the model on {adequacy_where(ctx)}: RMS {ad.rms_fit:.4g}, against a floor the data do not determine"
    return (f"; the model on {adequacy_where(ctx)}: RMS {ad.rms_fit:.4g} = {ad.ratio:.3g} x the floor "
            f"{ad.floor.sigma:.4g} ({ad.verdict})")


def changed_or_inadequate(ctx: Context, gap_before: float, gap_ref: float, n_val: int, min_ratio: float,
                          id_err: dict | None, generalise_ratio: float) -> str:
    """Why the verdict is ``unexplained`` where the identified model misses the validation records
    and its refit on the diagnosis's own fit records (h, F and G re-estimated, ``gap_ref``) reaches
    the floor; ``""`` where that is not so, or where the refit's gap is the honest reading.

    The refit shows that a model of the same structure fits the plant as it is now. If the
    identified model also misses its own records (:func:`fails_own_records`: it was fitted across
    a change, or cannot fit them), or misses the validation records more than ``generalise_ratio``
    times as far as its own (the plant changed after it was identified), the plant changed or the
    model was not adequate, and no effect is credited with the refit's shrink. Where neither holds,
    the identified model's error is its own and the verdict follows the refit's gap (``none``)."""
    if not ctx.identified:
        return ""
    floor = ctx.floor
    if not gap.gap_test(gap_before, n_val, floor, min_ratio=min_ratio).significant:
        return ""
    if gap.gap_test(gap_ref, n_val, floor, min_ratio=min_ratio).significant:
        return ""
    misfit = fails_own_records(ctx, min_ratio)
    own = float((id_err or {}).get("gap", 0.0) or 0.0)
    over_own = gap_before / max(own, floor.sigma) if (id_err or {}).get("records") else 0.0
    if misfit is None and not over_own > generalise_ratio:
        return ""
    if misfit is not None:
        rms = misfit.rms_fit if misfit.rms_held_out is None else max(misfit.rms_fit, misfit.rms_held_out)
        cause = (f"it misses {adequacy_where(ctx)} too (RMS {rms:.4g} = {misfit.ratio:.3g}x their floor): the plant "
                 "changed while it was identified, or the model was not adequate")
    else:
        cause = (f"it misses them {over_own:.3g}x as far as its own records: the plant changed since it was "
                 "identified, or the model was not adequate beyond its own records")
    why = (f"the identified model misses the validation records by {gap_before / floor.sigma:.3g}x the noise floor "
           f"{floor.sigma:.4g}, while the same model refitted on the diagnosis's own records reaches it "
           f"({gap_ref:.4g} = {gap_ref / floor.sigma:.3g}x); {cause}. No effect is credited with what the refit "
           "removes: unexplained")
    return why
