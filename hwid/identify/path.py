"""One identification path: the model of a config's plant, the same for every command.

``hwid run``, ``hwid diagnose`` (live and from logs) and the Python API call :func:`identify`;
``hwid identify-nonlinear`` and ``hwid identify-linear`` call its two steps, :func:`stage1` and
:func:`stage2`, which :func:`identify` calls itself: one recipe for every entry point.

A plant that runs experiments (simulated or live):

1. stage 1 from the staircases (Section 4, :mod:`hwid.identify.nonlinear`); where its levels fit
   only behind an input dead zone (:mod:`hwid.identify.deadzone_ahead`), stage 1 behind it and
   stage 2 driven through its inverse; the dead zone stays in the model (:class:`hwid.model.Actuator`);
2. the pre-compensator checked (:func:`hwid.identify.sine_runs.unsafe_precompensator`); stage 2
   through it (Section 5), run again with smaller sines while its outputs rest on a sensor rail
   (:func:`sines_off_the_rails`);
3. the two stages' model, or, where they cannot stand for the plant (an unsafe pre-compensator,
   :func:`g_undetermined`), the whole model fitted to the same records with the input's slew rate
   (:func:`hwid.identify.whole_rate.fit_rate_first`);
4. either judged on its own records (:func:`hwid.adequacy.assess`): a misfit is fitted again whole
   from itself, and the fit that reaches the records replaces it (:func:`stages_or_whole`,
   :func:`_whole_again`).

A recorded plant: the records split into a fit part and a held-out part (:mod:`hwid.identify.split`);
stage 1 from the fit part's levels starts the borders of the whole fit on the fit part (where it
cannot, the whole fit starts from a grid and says so), which adds G's delay, the input's slew rate
and its clip where the criterion prefers them (:mod:`hwid.identify.whole_delay`,
:mod:`~hwid.identify.whole_rate`, :mod:`~hwid.identify.whole_clip`); the model keeps them. Stage 1
from all the records' levels and stage 2 from their periodic stretches are reported beside it.

Every model is then assessed on its own records and the held-out ones
(:func:`hwid.adequacy.assess`, where that module is present).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from hwid import HwidError, adequacy
from hwid.identify.defaults import CLEARLY_BETTER, MODEL_ERROR_RATIO, RAIL_SHRINK, RAIL_TRIES
from hwid.identify.rails import rail_values
from hwid.identify.result import point_text
from hwid.masks import runs
from hwid.model import Actuator, HWModel
from hwid.rundir import HISTORY, LINEAR, NONLINEAR, RIG_JOURNAL, WHOLE


@dataclass(frozen=True)
class Identification:
    """The identified model and how it was reached.

    ``model``: the complete model (F, G with its delay, h_bar, and the actuator ahead of F where
    one was fitted), or None where the config runs stage 1 alone. ``route``: ``"stages"``,
    ``"whole"`` or ``"stage 1 only"``; ``why``: one sentence. ``records``: what the model was
    fitted on; ``held_out``: records kept out of the fit (a recorded plant's validation part);
    ``starts``: each fit record's initial state as the whole fit estimated it."""

    model: HWModel | None
    route: str
    why: str
    records: tuple = ()
    held_out: tuple = ()
    starts: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    nonlinear: object = None
    linear: object = None
    history: object = None
    whole: object = None
    nonlinear_records: tuple = ()
    linear_records: tuple = ()
    u_range: tuple | None = None
    w_range: tuple | None = None
    split: str = ""
    paths: dict = field(default_factory=dict)
    adequacy: object = None

    def to_dict(self) -> dict:
        """Plain data for the JSON summaries (the model, the route and why, the notes, adequacy)."""
        return {"route": self.route, "why": self.why, "model": None if self.model is None else self.model.to_dict(),
                "notes": list(self.notes), "split": self.split,
                "records": [r.name for r in self.records], "held_out": [r.name for r in self.held_out],
                "adequacy": None if self.adequacy is None else self.adequacy.to_dict()}


def identify(cfg, *, plant=None, records=None, out_dir=None, echo=print, stage_results: bool = True) -> Identification:
    """The model of ``cfg``'s plant (module docstring).

    Parameters
    ----------
    plant : a plant from :func:`hwid.plant.make_plant`, optional
        The plant to run the staircases and sines on (default: a new one of ``cfg``).
    records : sequence of :class:`hwid.plant.Record`, optional
        A recorded plant's records (default: :func:`hwid.recorded.load_records`).
    out_dir : path, optional
        Where the results go: ``nonlinear.h5``, ``linear.h5`` (the stages), ``history.h5`` (stage 1
        from a recorded plant's levels), ``whole.h5`` (the whole fit).
    stage_results : bool
        For a recorded plant, also stage 1 from all the records' levels and stage 2 from their
        periodic stretches (reported; the model does not use them). The diagnosis skips them.
    """
    out = None if out_dir is None else Path(out_dir)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    if cfg.plant.kind == "recorded" or records is not None:
        if records is None:
            from hwid.recorded import load_records
            records = load_records(cfg)
        ident = _from_records(cfg, [r for r in records if r.y is not None], out, echo, stage_results)
    else:
        ident = _from_plant(cfg, _new_plant(cfg, out) if plant is None else plant, out, echo)
    return assessed(ident, echo)


def assessed(ident: Identification, echo=print) -> Identification:
    """``ident`` with its adequacy (:func:`hwid.adequacy.assess` on the fit records and the held-out
    ones, off the sensor's rails); unchanged where there is no model."""
    if ident.model is None:
        return ident
    fit = [r for r in ident.records if r.y is not None]
    held = [r for r in ident.held_out if r.y is not None]
    if not fit:
        return ident
    result = adequacy.assess(ident.model, fit, held, starts=ident.starts or None, off_rails=rail_values(fit + held))
    echo(f"adequacy: {result.verdict} ({result.reason})")
    return replace(ident, adequacy=result)


# --------------------------------------------------------------------------- the two stages, as the path runs them

@dataclass(frozen=True)
class StageOne:
    """Stage 1 as the path reads it (:func:`stage1`).

    ``result``: a simulated or live plant's :class:`~hwid.identify.result.NonlinearResult` (behind
    the input dead zone its levels fit behind, where there is one: ``fit["deadzone_ahead"]``), or a
    recorded plant's :class:`~hwid.identify.result.HistoryResult`. ``records``: what it was read
    from (the staircases, or the records with an output). ``notes``: what the path said of it
    beyond the result's own warnings. ``paths``: the file written (``nonlinear`` or ``history``)."""

    result: object
    records: tuple = ()
    notes: tuple[str, ...] = ()
    paths: dict = field(default_factory=dict)


@dataclass(frozen=True)
class StageTwo:
    """Stage 2 as the path reads it (:func:`stage2`).

    ``linear``: the :class:`~hwid.identify.result.LinearResult`, or None where stage 2 is not run
    (``why``: an unsafe pre-compensator, no periodic stretch in the records). ``records``: the sine
    records as the plant received them, or a recorded plant's periodic pieces. ``cfg``: the config
    whose sines were used (smaller than the given one's where the outputs rested on a sensor rail:
    :func:`sines_off_the_rails`). ``paths``: ``linear`` where written."""

    linear: object
    records: tuple = ()
    cfg: object = None
    why: str = ""
    paths: dict = field(default_factory=dict)


def stage1(cfg, *, plant=None, records=None, data=None, out_dir=None, echo=print) -> StageOne:
    """Stage 1 of the path, the one recipe ``hwid run``, ``hwid identify-nonlinear`` and the
    diagnosis share: for a plant that runs experiments, the staircases (Section 4,
    :func:`hwid.identify.nonlinear.identify_nonlinear`) and, where their levels fit only behind an
    input dead zone, stage 1 behind it (:mod:`hwid.identify.deadzone_ahead`), ``nonlinear.h5``; for
    a recorded plant, the levels of every record with an output
    (:func:`hwid.identify.history.identify_recorded`: disturbed holds left out, what the levels
    cannot determine said so), ``history.h5``. Written where ``out_dir`` is given, and said.

    Parameters
    ----------
    plant : optional
        The plant to run the staircases on (default: a new one of ``cfg``, journalled in
        ``out_dir/rig_journal``).
    records : sequence of :class:`hwid.plant.Record`, optional
        A recorded plant's records (default: :func:`hwid.recorded.load_records`).
    data : path or mapping, optional
        The staircases as recorded before (a ``simulation.h5``) instead of running them.

    Raises
    ------
    HwidError
        Where stage 1 cannot be read from the data (no staircase, too few levels): one line.
    """
    out = None if out_dir is None else Path(out_dir)
    if cfg.plant.kind == "recorded" or records is not None:
        return _stage1_levels(cfg, records, out, echo)
    return _stage1_staircases(cfg, plant, data, out, echo)


def stage2(cfg, nonlinear, *, plant=None, records=None, out_dir=None, echo=print) -> StageTwo:
    """Stage 2 of the path after :func:`stage1`'s ``nonlinear``: for a plant that runs experiments,
    the sines through the pre-compensator (Section 5; behind stage 1's input dead zone, through its
    inverse too), run again smaller while the outputs rest on a rail (:func:`sines_off_the_rails`),
    not run where the pre-compensator is unsafe
    (:func:`hwid.identify.sine_runs.unsafe_precompensator`); for a recorded plant, the records'
    steady periodic stretches (:func:`hwid.identify.periodic.identify_periodic`). ``linear.h5``
    where ``out_dir`` is given. Arguments as :func:`stage1`'s."""
    out = None if out_dir is None else Path(out_dir)
    if cfg.plant.kind == "recorded" or records is not None:
        return _stage2_periodic(cfg, nonlinear, records, out, echo)
    return _stage2_sines(cfg, nonlinear, plant, out, echo)


def _new_plant(cfg, out: Path | None):
    from hwid.plant import make_plant
    return make_plant(cfg, journal_dir=None if out is None else out / RIG_JOURNAL)


def _stage1_staircases(cfg, plant, data, out: Path | None, echo) -> StageOne:
    from hwid.identify.deadzone_ahead import find_deadzone
    from hwid.identify.nonlinear import identify_nonlinear
    t0 = time.perf_counter()
    if data is None and plant is None:
        plant = _new_plant(cfg, out)
    nonlinear, records = identify_nonlinear(cfg, plant=plant, data=data)
    ahead = find_deadzone(cfg, nonlinear, records)
    notes = []
    if ahead is not None:
        echo(ahead.note())
        notes.append(ahead.note())
        nonlinear = _behind(ahead)
    paths = {}
    if out is not None:
        from hwid.results import write_nonlinear
        paths["nonlinear"] = write_nonlinear(out / NONLINEAR, cfg, nonlinear, records)
    ci = nonlinear.ci
    echo(f"stage 1: {nonlinear.type}, d+ = {point_text(nonlinear.d_plus, ci['d_plus'])}, S^d = "
         f"{point_text(nonlinear.slope_down, ci['slope_down'])}, d- = {point_text(nonlinear.d_minus, ci['d_minus'])}, "
         f"degree {nonlinear.degree} ({time.perf_counter() - t0:.1f} s)")
    return StageOne(nonlinear, tuple(records), tuple(notes), paths)


def _stage1_levels(cfg, records, out: Path | None, echo) -> StageOne:
    from hwid.identify.history import identify_recorded
    if records is None:
        from hwid.recorded import load_records
        records = load_records(cfg)
    records = [r for r in records if r.y is not None]
    hist = identify_recorded(cfg, records)
    paths = {}
    if out is not None:
        from hwid.results import write_history
        paths["history"] = write_history(out / HISTORY, cfg, hist)
    band = hist.ci.get("dead_band")      # None where the levels cannot determine it
    echo(f"stage 1 from the levels: {hist.type}, d+ = {point_text(hist.d_plus, hist.ci['d_plus'])}, "
         f"d- = {point_text(hist.d_minus, hist.ci['d_minus'])}, dead band "
         + (f"{hist.dead_band:.4g} [{band[0]:.4g}, {band[1]:.4g}]" if band is not None else
            f"undetermined (fitted {hist.dead_band:.4g}, not a measurement)")
         + f", S^d = {hist.slope_down:.4g}{' (MISFIT)' if hist.misfit else ''}")
    for w in hist.warnings:
        echo(f"warning: {w}")
    return StageOne(hist, tuple(records), (), paths)


def _stage2_sines(cfg, nonlinear, plant, out: Path | None, echo) -> StageTwo:
    from hwid.identify.deadzone_ahead import ThroughDeadZone
    from hwid.identify.sine_runs import unsafe_precompensator
    unsafe = unsafe_precompensator(cfg, nonlinear)
    if unsafe:
        return StageTwo(None, (), cfg, unsafe)
    plant = _new_plant(cfg, out) if plant is None else plant
    delta = deadzone_behind(nonlinear)
    drive = ThroughDeadZone(plant, delta) if delta > 0 else plant   # F sees the pre-compensated sine
    linear, records = _stage2(cfg, nonlinear, drive, echo)
    cfg, linear, records = sines_off_the_rails(cfg, nonlinear, linear, records, drive, echo)
    if drive is not plant:     # the records as the plant received them, for the diagnosis and the files
        records = [drive.sent.get(r.name, r) for r in records]
    paths = {}
    if out is not None:
        from hwid.results import write_linear
        paths["linear"] = write_linear(out / LINEAR, cfg, linear, records)
    echo(f"stage 2: G(jw) at {len(linear.frequencies)} frequencies; G = "
         f"{_coefficients(linear.parametric.get('num', []))}/{_coefficients(linear.parametric.get('den', []))}")
    for w in linear.warnings:
        echo(f"warning: {w}")
    return StageTwo(linear, tuple(records), cfg, "", paths)


def _stage2_periodic(cfg, hist, records, out: Path | None, echo) -> StageTwo:
    from hwid.identify.linear import ExtrapolationWarning
    from hwid.identify.periodic import identify_periodic, periodic_pieces
    if records is None:
        from hwid.recorded import load_records
        records = load_records(cfg)
    records = [r for r in records if r.y is not None]
    if not periodic_pieces(records)[0]:
        return StageTwo(None, (), cfg, "the records hold no steady periodic stretch")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)     # said below from the result
        lin, pieces = identify_periodic(cfg, records, hist)
    paths = {}
    if out is not None:
        from hwid.results import write_linear
        paths["linear"] = write_linear(out / LINEAR, cfg, lin, pieces)
    echo(f"stage 2 from {len(lin.frequencies)} periodic stretch(es): G(jw) at "
         f"{', '.join(f'{w:.4g}' for w in lin.frequencies)} rad/s")
    for w in lin.warnings:
        echo(f"warning: {w}")
    return StageTwo(lin, tuple(pieces), cfg, "", paths)


# --------------------------------------------------------------------------- a plant that runs experiments

def _from_plant(cfg, plant, out: Path | None, echo) -> Identification:
    """Steps 1-3 of the module docstring on ``plant``."""
    from hwid.identify.sine_runs import run_sines
    one = stage1(cfg, plant=plant, out_dir=out, echo=echo)
    nonlinear, nl_records, notes = one.result, list(one.records), list(one.notes)
    base = dict(nonlinear=nonlinear, nonlinear_records=one.records, paths=dict(one.paths))
    levels = list(cfg.protocols.staircase.levels_up) + list(cfg.protocols.staircase.levels_down)
    u_range = (float(min(levels)), float(max(levels)))
    if cfg.protocols.sine is None:
        if not cfg.identification.whole.enabled:
            return Identification(None, "stage 1 only", "the config has no sines: stage 2 is not run",
                                  records=tuple(nl_records), notes=tuple(notes), u_range=u_range, **base)
        return _whole_from_stages(cfg, None, nl_records, out, echo, notes, u_range, base)
    two = stage2(cfg, nonlinear, plant=plant, out_dir=out, echo=echo)
    if two.linear is None:
        echo("stage 1 did not identify F: stage 2 is not run, and the sines drive the plant without a "
             "pre-compensator")
        _, lin_records = run_sines(cfg, None, plant=plant)
        return _whole_instead(cfg, nl_records + list(lin_records), out, two.why, echo, notes,
                              {**base, "linear_records": tuple(lin_records)})
    cfg, linear = two.cfg, two.linear
    base = {**base, "linear": linear, "linear_records": two.records, "paths": {**base["paths"], **two.paths}}
    records = [r for r in nl_records + list(two.records) if r.y is not None]
    why = g_undetermined(linear)
    if why:
        return _whole_instead(cfg, records, out, why, echo, notes, base)
    stage_notes: list = []
    model = stages_model(nonlinear, linear, stage_notes)
    for note in stage_notes:
        echo(note)
    ident = Identification(model, "stages", "the two stages identified F, h and G", records=tuple(records),
                           notes=tuple(notes + stage_notes), u_range=u_range,
                           w_range=tuple(float(x) for x in nonlinear.w_range), **base)
    return stages_or_whole(cfg, ident, out, echo)


def stages_or_whole(cfg, ident: Identification, out, echo=print) -> Identification:
    """The two stages' model, or the whole model fitted from it where theirs misses its own records.

    The stages read h from the staircases' levels and G from the sines' harmonics; neither is
    fitted to the records as a whole, and where the sines drive G's output beyond the levels'
    range, h is extrapolated there (the paper's plant: a quintic h read on [-0.90, 0.70] and run to
    +-0.99 by the slowest sine missed it by 3x the noise, its own records by 2.3x). Their model is
    judged on its own records off the sensor's rails (:func:`hwid.adequacy.assess`, the rails'
    samples set aside as the stages set them aside); where it is a misfit by more than the model
    error an identified model is allowed (:data:`~hwid.identify.defaults.MODEL_ERROR_RATIO`), the whole fit
    started from it (:func:`hwid.identify.whole_again.fits_from`, on the staircases and the sines'
    last periods) is judged on the same records the same way, and replaces it where it is adequate or its RMS is at most
    :data:`~hwid.identify.defaults.CLEARLY_BETTER` of theirs; the route then says so. A model that
    cannot be judged on its records (its G so slow that nothing is left after the burn-in, on a
    floor the data determine) is replaced by a whole fit that can be, adequate or not. With
    ``identification.whole.enabled`` the whole fit runs beside in any case (``whole.h5``). A model
    behind an input dead zone (stage 1's, :func:`deadzone_behind`) stays the stages': the whole fit
    has no dead zone ahead of F."""
    rails = rail_values(ident.records)
    stages = adequacy.assess(ident.model, ident.records, off_rails=rails)
    # undetermined on a determined floor: too few samples after the burn-in of a G so slow that
    # its records hold nothing past it (a folded h read as a line by stage 1: a pole at 0.09 rad/s
    # for the plant's 1.5, 148x the floor on the diagnosis's records)
    unjudged = stages.verdict == "undetermined" and stages.floor.determined
    relevant = stages.verdict == "misfit" and stages.ratio ** 2 > MODEL_ERROR_RATIO
    switch = (relevant or unjudged) and ident.model.actuator is None
    if not switch:
        return _whole_beside(cfg, ident, ident.model, out, echo) if cfg.identification.whole.enabled else ident
    echo(f"the two stages' model {'cannot be judged on' if unjudged else 'misses'} its own records "
         f"({stages.reason}): the whole model is fitted from it to the staircases and the sines' last periods")
    from hwid.identify.whole import fit_records
    from hwid.identify.whole_again import fits_from
    t0 = time.perf_counter()
    whole, fitter = fits_from(cfg, ident.model, fit_records(list(ident.nonlinear_records) + list(ident.linear_records)),
                              lambda res: adequacy.assess(res.model(), ident.records, off_rails=rails)) or (None, None)
    if whole is None:       # no whole fit could start from the stages' model: theirs stays
        return ident
    res, paths = _said(cfg, fitter, out, echo, t0, role="beside")
    beside = replace(ident, whole=res, paths={**ident.paths, **paths})
    whole_model = res.model()
    judged = unjudged and whole.verdict == "misfit" and np.isfinite(whole.rms_fit)   # beats one never judged
    if whole.verdict != "adequate" and not judged and (unjudged or not whole.rms_fit <= CLEARLY_BETTER * stages.rms_fit):
        note = (f"the whole model fitted from the stages' is no better on their records (RMS {whole.rms_fit:.4g} "
                f"for their {stages.rms_fit:.4g}): the model stays the stages'")
        echo(note)
        return replace(beside, notes=beside.notes + (note,))
    why = ((f"the two stages' model cannot be judged on its own records ({stages.reason})" if unjudged else
            f"the two stages' model misses its own records (RMS {stages.rms_fit:.4g} = {stages.ratio:.3g} x the "
            "noise floor)") + f"; the whole model fitted from it reaches {whole.rms_fit:.4g} = {whole.ratio:.3g} x")
    echo(f"{why}: the model is the whole fit's")
    if out is not None:        # whole.h5 is now the run's model, not a fit beside it
        from hwid.results import write_whole
        write_whole(out / WHOLE, cfg, beside.whole, "model")
    w = np.concatenate([whole_model.input.apply(r.u) for r in ident.records])
    return replace(beside, model=whole_model, route="whole", why=why, notes=beside.notes + (why,),
                   w_range=(float(w.min()), float(w.max())))


def _behind(ahead):
    """Stage 1's result behind the dead zone ``ahead`` found, marked so (``fit["deadzone_ahead"]``
    with ``behind``), as ``nonlinear.h5`` keeps it and :func:`stages_model` reads it."""
    r = ahead.result
    fit = {**r.fit, "deadzone_ahead": {**ahead.to_dict(), "behind": True}}
    return replace(r, fit=fit, warnings=tuple(r.warnings) + (ahead.note(),))


def stages_model(nonlinear, linear, notes: list | None = None) -> HWModel:
    """The model of the two stages (:func:`hwid.identify.result.model_from_stages`), with the input
    dead zone stage 1 was identified behind (:func:`_behind`) as its actuator."""
    from hwid.identify.result import model_from_stages
    model = model_from_stages(nonlinear, linear, notes)
    delta = deadzone_behind(nonlinear)
    if delta > 0:
        model = replace(model, actuator=Actuator(deadzone=delta))
    return model


def deadzone_behind(nonlinear) -> float:
    """The width of the input dead zone stage 1's ``nonlinear`` was identified behind (:func:`_behind`;
    kept in ``fit["deadzone_ahead"]``, which ``nonlinear.h5`` keeps), or 0."""
    found = (getattr(nonlinear, "fit", None) or {}).get("deadzone_ahead") or {}
    return float(found.get("delta", 0.0)) if found.get("behind") else 0.0


def _stage2(cfg, nonlinear, drive, echo):
    from hwid.identify.linear import ExtrapolationWarning, identify_linear
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)     # said from the result's warnings
        return identify_linear(cfg, nonlinear, plant=drive)


def sines_off_the_rails(cfg, nonlinear, linear, records, plant, echo):
    """Stage 2 again with sines :data:`RAIL_SHRINK` times as large, up to :data:`RAIL_TRIES` times,
    while its outputs rest on a sensor rail (:mod:`hwid.identify.rails`): a clipped output's
    harmonics are not those of ``h(G w)``, and G read from them is wrong where no effect's refit
    reaches it. The validation experiments still cover the staircases' range, where the clip is the
    diagnosis's to find. Returns the config whose sines were used, and stage 2's result and records."""
    from hwid.identify.rails import describe, find_rails
    for _ in range(RAIL_TRIES):
        found = find_rails([r.y for r in records if r.y is not None], [r.name for r in records if r.y is not None])
        if not found:
            break
        sine = cfg.protocols.sine.model_copy(update={"amplitude": RAIL_SHRINK * cfg.protocols.sine.amplitude})
        echo(f"stage 2's sines: {describe(found, cfg.sampling.dt)}; run again at amplitude {sine.amplitude:.3g}")
        cfg = cfg.model_copy(update={"protocols": cfg.protocols.model_copy(update={"sine": sine})})
        linear, records = _stage2(cfg, nonlinear, plant, echo)
    return cfg, linear, records


def g_undetermined(linear) -> str:
    """Why stage 2's G cannot stand for the plant's, or ``""``: at half its sines or more no harmonic
    of the output rose above the noise (the plant did not follow them: a slow actuator, a stuck
    gear), or its parametric G has a pole within 1e-6 of the lowest sine's frequency of zero (the
    fit's answer to gains that fall to nothing across the band, ``1.5e-15/(s + 1.5e-15)``). Either
    way two stages read from harmonics have nothing to read; the staircases and sines still hold
    the plant's response, for a fit of the whole model."""
    n = len(linear.frequencies)
    lost = sum(np.size(h.get("significant_harmonics", [1])) == 0 for h in linear.harmonics)
    if n and 2 * lost >= n:
        return f"stage 2 could not determine G at {lost} of its {n} sines (no harmonic above the noise)"
    den = np.atleast_1d(np.asarray((linear.parametric or {}).get("den", []), float))
    if den.size > 1 and n:
        poles = np.roots(np.trim_zeros(den, "f"))
        if poles.size and np.min(np.abs(poles)) < 1e-6 * float(np.min(linear.frequencies)):
            return f"stage 2's G has a pole at {np.min(np.abs(poles)):.3g} rad/s, nothing below its sines"
    return ""


def _whole_instead(cfg, records, out, why: str, echo, notes: list, base: dict) -> Identification:
    """The model fitted whole to the staircases and sines, with the input's slew rate from the start,
    where the two stages cannot stand for the plant (``why``): the records still hold its response."""
    from hwid.identify.whole import WholeModelFit
    echo(f"{why}: the model is fitted whole to the staircases and sines, with the input's slew rate")
    records = [r for r in records if r.y is not None]
    t0 = time.perf_counter()
    res, paths = _said(cfg, WholeModelFit.from_config(cfg, staged=True).fit_rate_first(records), out, echo, t0)
    model = res.model()
    w = np.concatenate([model.input.apply(model.actuate(r.u, r.dt)) for r in records])   # the w the records reached
    u = np.concatenate([r.u for r in records])
    ident = Identification(model, "whole", f"{why}: the whole model, fitted with the input's slew rate",
                           records=tuple(records), starts=dict(res.initial_states),
                           notes=tuple(notes + [why] + list(res.warnings)), whole=res,
                           u_range=(float(u.min()), float(u.max())), w_range=(float(w.min()), float(w.max())),
                           **{**base, "paths": {**base.get("paths", {}), **paths}})
    return _whole_again(cfg, ident, out, echo)


def _whole_again(cfg, ident: Identification, out, echo=print) -> Identification:
    """The whole model fitted with the input's slew rate from the start (:func:`_whole_instead`), or,
    where it misses its own records, a whole fit without the actuator started from it.

    The fit with a rate from the start descends from a few joint starts of borders, rate and memory
    at h_bar's highest degree; where the rate it finds is only a stand-in, the fits without it reach
    the records: first from its F, G and h (G's structure, h_bar's neighbouring degrees; a
    Backlash-Inverse before a folded h slewing at 120 units/s across a range of 3 went from 1.18x
    the noise on its own records to 1.03x), then, where that is still a misfit, from its borders
    with every G structure and degree (:meth:`~hwid.identify.whole.WholeModelFit.fit` with
    ``borders``, staged: one whose G had kept a pole-zero pair at 0.36 / 0.38 rad/s for the plant's
    pole at 9.8 rad/s went from 2.9x to 0.98x). Each judged on the same records from its own
    starts (:func:`hwid.adequacy.assess`); the best kept where adequate or its RMS is at most
    :data:`~hwid.identify.defaults.CLEARLY_BETTER` of the first's, as in :func:`stages_or_whole`.
    A rate the records need stays: the fits without it are then no better."""
    from hwid.identify.whole_again import fits_from
    first = adequacy.assess(ident.model, ident.records, starts=ident.starts or None)
    if first.verdict != "misfit":
        return ident
    echo(f"the whole model misses its own records ({first.reason}): fitted again from it without its actuator")
    t0 = time.perf_counter()
    records = list(ident.records)
    again, fitter = fits_from(cfg, ident.model.without_actuator(), records,
                              lambda res: adequacy.assess(res.model(), records, starts=res.initial_states)) or (None, None)
    if again is None or again.verdict != "adequate" and not again.rms_fit <= CLEARLY_BETTER * first.rms_fit:
        note = ("no whole fit could start from it without its actuator" if again is None else f"the whole fit from "
                f"it without its actuator is no better on its records (RMS {again.rms_fit:.4g} for {first.rms_fit:.4g})"
                ) + ": the model keeps its actuator"
        echo(note)
        return replace(ident, notes=ident.notes + (note,))
    res, paths = _said(cfg, fitter, out, echo, t0)
    model = res.model()
    why = (f"{ident.why}; it missed its own records (RMS {first.rms_fit:.4g} = {first.ratio:.3g} x the noise "
           f"floor), the whole fit from it without its actuator reaches {again.rms_fit:.4g} = {again.ratio:.3g} x")
    echo(why)
    w = np.concatenate([model.input.apply(r.u) for r in ident.records])
    return replace(ident, model=model, why=why, starts=dict(res.initial_states), whole=res,
                   notes=ident.notes + (why,) + tuple(res.warnings), w_range=(float(w.min()), float(w.max())),
                   paths={**ident.paths, **paths})


def _whole_from_stages(cfg, start, records, out, echo, notes, u_range, base) -> Identification:
    """Sines absent but ``identification.whole.enabled``: the whole model fitted to the staircases."""
    from hwid.identify.whole import WholeModelFit, fit_records
    t0 = time.perf_counter()
    res, paths = _said(cfg, WholeModelFit.from_config(cfg).fit(fit_records(records), start=start), out, echo, t0)
    return Identification(res.model(), "whole", "the config has no sines: the whole model, fitted to the staircases",
                          records=tuple(records), starts=dict(res.initial_states), notes=tuple(notes), whole=res,
                          u_range=u_range, **{**base, "paths": {**base.get("paths", {}), **paths}})


def _whole_beside(cfg, ident: Identification, start: HWModel, out, echo) -> Identification:
    """``identification.whole.enabled`` beside the two stages: the whole fit from their model on the
    staircases and the sines' last periods (``whole.h5``); the model stays the stages'."""
    from hwid.identify.whole import WholeModelFit, fit_records
    t0 = time.perf_counter()
    records = fit_records(list(ident.nonlinear_records) + list(ident.linear_records))
    res, paths = _said(cfg, WholeModelFit.from_config(cfg).fit(records, start=start.without_actuator()), out,
                       echo, t0, role="beside")
    return replace(ident, whole=res, paths={**ident.paths, **paths})


def _said(cfg, fitter, out, echo, t0: float, role: str = "model"):
    """The whole fit's result, written (``whole.h5`` in the ``role`` of :func:`hwid.results.write_whole`)
    and said; ``(result, paths)``."""
    res = fitter.result_
    paths = {}
    if out is not None:
        from hwid.results import write_whole
        paths["whole"] = write_whole(out / WHOLE, cfg, res, role)
    act = res.actuator
    echo(f"whole model ({time.perf_counter() - t0:.1f} s): {res.type}, d+ = {point_text(res.d_plus, res.ci['d_plus'])}, "
         f"d- = {point_text(res.d_minus, res.ci['d_minus'])}, "
         f"S^d = {point_text(res.slope_down, res.ci['slope_down'])}, "
         f"h degree {len(res.h_coefficients) - 1}, G {res.structure}"
         + (f" with a delay of {res.delay:.4g} s" if res.delay > 0 else "") + f", sigma {res.sigma:.4g}"
         + (f"; the input slews at {act.rate:.4g} units/s" if act is not None and act.rate else "")
         + (f"; the input is clipped to [{act.clip[0]:.4g}, {act.clip[1]:.4g}]"
            if act is not None and act.clip else ""))
    for w in res.warnings:
        echo(f"warning: {w}")
    return res, paths


def _coefficients(c) -> str:
    """A polynomial's coefficients as a plain list, four significant digits."""
    return "[" + ", ".join(f"{float(x):.4g}" for x in np.atleast_1d(np.asarray(c, float))) + "]"


# --------------------------------------------------------------------------- a recorded plant

def input_moves(cfg, records, what: str = "the records' input") -> None:
    """:class:`hwid.HwidError` (one line) where ``records``' input (``what``: which records, for the
    message) does not move enough to identify anything from: fewer than three distinct values (a
    play, G and h cannot be told apart from one or two levels)."""
    u = np.concatenate([np.asarray(r.u, float) for r in records])
    distinct = np.unique(u[np.isfinite(u)])
    if distinct.size < 3:
        held = ", ".join(f"{x:.4g}" for x in distinct[:2])
        raise HwidError(f"{cfg.source_path}: {what} takes only {distinct.size} value(s) ({held}): "
                        "no model can be identified from it; record an input that moves across the play "
                        "(levels approached from both sides, or a sine)")


def _from_records(cfg, records, out: Path | None, echo, stage_results: bool) -> Identification:
    """A recorded plant (module docstring): split, stage results beside, the whole fit on the fit part."""
    from hwid.identify.split import fit_pieces, held_out_pieces, plan
    from hwid.recorded import describe
    if not records:
        raise HwidError(f"{cfg.source_path}: the records hold no output to identify a model from")
    echo(f"records: {describe(records)}")
    notes: list = []
    try:
        parts, how = plan(records)
        fit, held = fit_pieces(parts), held_out_pieces(parts)
    except HwidError as err:
        parts, fit, held, how = [], list(records), [], ""
        notes.append(f"{err}: the model is fitted on all of them and none is held out")
        echo(notes[-1])
    base: dict = {"paths": {}}
    if stage_results:
        base.update(_recorded_stages(cfg, records, out, echo))
    input_moves(cfg, fit, "the fit part's input" if held else "the records' input")
    t0 = time.perf_counter()
    fitter, how_borders = _whole_on_records(cfg, fit, echo)
    res, paths = _said(cfg, fitter, out, echo, t0)
    starts = {**held_starts(res.model(), parts, res.initial_states), **res.initial_states} if held else \
        dict(res.initial_states)
    u = np.concatenate([p.u for p in fit])
    why = ("a recorded plant: the whole model (G's delay, the input's slew rate and clip where the records "
           f"show them) fitted on {'the fit part' if held else 'all the records'}; {how_borders}")
    return Identification(res.model(), "whole", why, records=tuple(fit), held_out=tuple(held), starts=starts, notes=tuple(notes + list(res.warnings)), whole=res,
                          u_range=(float(u.min()), float(u.max())), split=how,
                          **{**base, "paths": {**base["paths"], **paths}})


def held_starts(model: HWModel, parts, starts: dict) -> dict:
    """Where each held-out block of a record split in blocks (:func:`hwid.identify.split.plan`)
    starts, as the fitted ``model`` puts it: the model run through the record from its first fit
    block's estimated start (``starts``, by piece name), read just before each held block: the
    gear (F's last output), G's level (its last output, G(0) = 1 as the whole fit normalises it)
    and, with a slew, the actuator's position. No held-out sample is used; a block's state is then
    judged from its first sample instead of after a burn-in. Empty where a record's first block
    has no estimated start."""
    out: dict = {}
    for r, role, samples in parts:
        if role != "validation" or samples.all():
            continue
        first = starts.get(f"{r.name}:fit0")
        if first is None or samples[0]:
            continue
        u = np.asarray(r.u, float)
        sig = model.simulate(u, r.dt, gear=first["gear"], rest=first["rest"], position=first.get("position"))
        acted = model.actuate(u, r.dt, first.get("position"))
        for k, (a, _) in enumerate(runs(samples)):
            if a == 0:
                continue
            st = {"gear": float(sig.v[a - 1]), "rest": float(sig.w[a - 1])}
            if model.actuator is not None and model.actuator.rate is not None:
                st["position"] = float(acted[a - 1])
            out[f"{r.name}:held{k}"] = st
    return out


def _whole_on_records(cfg, pieces, echo):
    """The whole fit on ``pieces``: stage 1 from their levels as the borders' start where they hold
    enough, G's delay fitted by name, then the input's slew rate and its clip added where the
    criterion prefers them. ``(fitter, how the borders started)``."""
    from hwid.identify.history import identify_recorded
    from hwid.identify.whole import WholeModelFit
    from hwid.model import InputNonlinearity
    try:
        hist = identify_recorded(cfg, pieces)
    except HwidError as err:
        borders, how = None, f"stage 1 from its levels: {err}; the borders start from a grid"
    else:
        borders = InputNonlinearity(hist.type, 1.0, hist.slope_down, hist.d_plus, hist.d_minus)
        how = "stage 1 from its levels started the borders"
        if hist.misfit:
            # levels the stage-1 model does not reach say little about F's type: a non-invertible
            # h_bar read from few levels gave a Backlash-Inverse of zero play for a plain Backlash
            borders, how = None, "stage 1 from its levels is a misfit: both types tried from a grid of borders"
        echo(f"stage 1 from the fit part's levels: {hist.type}, d+ = {point_text(hist.d_plus, hist.ci['d_plus'])}, "
             f"d- = {point_text(hist.d_minus, hist.ci['d_minus'])}, "
             f"S^d = {hist.slope_down:.4g}" + (" (misfit: not used)" if hist.misfit else ": the borders' start"))
    # G's pure delay fitted by name as well (a rational G alone stands in for a delay with fast poles the
    # plant does not have, and no excess phase is left for time_delay to name), then the slew and clip
    return WholeModelFit.from_config(cfg, staged=True).fit_actuated(pieces, borders=borders), how


def _recorded_stages(cfg, records, out: Path | None, echo) -> dict:
    """Stage 1 from all the records' levels (``history.h5``) and stage 2 from their periodic
    stretches (``linear.h5``), where they hold them (:func:`stage1`, :func:`stage2`): reported
    beside the model."""
    found: dict = {"paths": {}}
    try:
        one = stage1(cfg, records=records, out_dir=out, echo=echo)
    except HwidError as err:
        echo(f"stage 1 from the levels: skipped ({err})")
        return found
    found["history"] = one.result
    found["paths"].update(one.paths)
    two = stage2(cfg, one.result, records=records, out_dir=out, echo=echo)
    if two.linear is None:
        echo(f"stage 2 from periodic stretches: skipped ({two.why})")
        return found
    found["linear"] = two.linear
    found["paths"].update(two.paths)
    return found
