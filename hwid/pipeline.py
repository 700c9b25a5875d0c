"""``hwid run``: the whole job on one plant — staircases, stage 1, stage 2 through the estimated
pre-compensator, the report.

One plant object serves every experiment, as on a rig: the simulated gear keeps its state, and an
external rig's calls are journalled in ``OUT/rig_journal`` so a rerun after a failure reuses them.
Writes ``OUT/simulation.h5`` (the staircases as measured, and the truth when the plant is
simulated), ``OUT/nonlinear.h5``, ``OUT/linear.h5``, ``OUT/whole.h5`` (the whole-model fit, with
``identification.whole.enabled``) and ``OUT/report/``.
"""
from __future__ import annotations

import time
from pathlib import Path

from hwid import HwidError
from hwid.plant import make_plant
from hwid.results import write_linear, write_nonlinear, write_simulation, write_whole


def run(cfg, out_dir: str | Path, report: bool = True, echo=print) -> dict:
    """Run everything; return the paths written and the seconds each step took."""
    from hwid.identify import deadzone_ahead
    from hwid.identify.linear import identify_linear
    from hwid.identify.nonlinear import identify_nonlinear
    from hwid.simulate import truth

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if cfg.plant.kind == "recorded":
        return _run_recorded(cfg, out, report, echo)
    plant = make_plant(cfg, journal_dir=out / "rig_journal")
    times: dict[str, float] = {}
    paths: dict[str, Path] = {}

    t0 = time.perf_counter()
    nl, nl_records = identify_nonlinear(cfg, plant=plant)
    nl = deadzone_ahead.noted(cfg, nl, nl_records)
    paths["nonlinear"] = write_nonlinear(out / "nonlinear.h5", cfg, nl, nl_records)
    paths["simulation"] = write_simulation(out / "simulation.h5", cfg, nl_records, truth(cfg))
    times["stage1"] = time.perf_counter() - t0
    echo(f"stage 1: {nl.type}, d+ = {nl.d_plus:.4f}, S^d = {nl.slope_down:.4f}, d- = {nl.d_minus:.4f}, "
         f"degree {nl.degree} ({times['stage1']:.1f} s)")
    if "deadzone_ahead" in nl.fit:
        echo(f"warning: {nl.warnings[-1]}")

    if cfg.protocols.sine is not None:
        import warnings
        from hwid.identify.linear import ExtrapolationWarning
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExtrapolationWarning)     # echoed below from the result
            lin, lin_records = identify_linear(cfg, nl, plant=plant)
        paths["linear"] = write_linear(out / "linear.h5", cfg, lin, lin_records)
        times["stage2"] = time.perf_counter() - t0
        echo(f"stage 2: G(jw) at {len(lin.frequencies)} frequencies ({times['stage2']:.1f} s)")
        for w in lin.warnings:
            echo(f"warning: {w}")

    if cfg.identification.whole.enabled:
        from hwid.identify.result import model_from_stages
        from hwid.identify.whole import fit_records
        start = model_from_stages(nl, lin) if cfg.protocols.sine is not None else None
        _whole(cfg, fit_records(list(nl_records) + list(lin_records if start else [])), start, out, paths, times, echo)

    if report:
        from hwid.report.html import write_report
        t0 = time.perf_counter()
        paths["report"] = write_report(out)
        times["report"] = time.perf_counter() - t0
        echo(f"report: {paths['report']} ({times['report']:.1f} s)")
    return {"paths": paths, "seconds": times}


def _run_recorded(cfg, out: Path, report: bool, echo) -> dict:
    """A recorded plant: its records to ``simulation.h5``; stage 1 from their levels where they hold
    enough (``history.h5``); the whole-model fit on them when ``identification.whole.enabled``."""
    from hwid.identify.history import identify_recorded
    from hwid.identify.result import interval_text
    from hwid.recorded import describe, load_records
    from hwid.results import write_history
    times: dict[str, float] = {}
    paths: dict[str, Path] = {}
    t0 = time.perf_counter()
    records = load_records(cfg)
    paths["simulation"] = write_simulation(out / "simulation.h5", cfg, records, None)
    echo(f"records: {describe(records)}")
    try:
        hist = identify_recorded(cfg, records)
    except HwidError as err:
        if not cfg.identification.whole.enabled:
            raise HwidError(f"{cfg.source_path}: {err}; set identification.whole.enabled: true to fit the whole "
                            "model on any input") from None
        echo(f"stage 1 from the levels: skipped ({err})")
    else:
        paths["history"] = write_history(out / "history.h5", cfg, hist)
        times["history"] = time.perf_counter() - t0
        echo(f"stage 1 from the levels: {hist.type}, d+ = {hist.d_plus:.4g}, d- = {hist.d_minus:.4g}, dead band "
             f"{interval_text(hist.dead_band, hist.ci['dead_band'], 4)}, "
             f"S^d = {hist.slope_down:.4g}{' (MISFIT)' if hist.misfit else ''}")
        for w in hist.warnings:
            echo(f"warning: {w}")
        _periodic(cfg, records, hist, out, paths, times, echo)
    if cfg.identification.whole.enabled:
        _whole(cfg, records, None, out, paths, times, echo)
    if report:
        from hwid.report.html import write_report
        paths["report"] = write_report(out)
        echo(f"report: {paths['report']}")
    return {"paths": paths, "seconds": times}


def _periodic(cfg, records, hist, out: Path, paths: dict, times: dict, echo) -> None:
    """Stage 2 from the records' steady periodic stretches, where they hold any (``linear.h5``)."""
    import warnings
    from hwid.identify.linear import ExtrapolationWarning
    from hwid.identify.periodic import identify_periodic, periodic_pieces
    if not periodic_pieces(records)[0]:
        echo("stage 2 from periodic stretches: skipped (the records hold no steady periodic stretch)")
        return
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)     # echoed below from the result
        lin, pieces = identify_periodic(cfg, records, hist)
    paths["linear"] = write_linear(out / "linear.h5", cfg, lin, pieces)
    times["stage2"] = time.perf_counter() - t0
    echo(f"stage 2 from {len(lin.frequencies)} periodic stretch(es): G(jw) at "
         f"{', '.join(f'{w:.4g}' for w in lin.frequencies)} rad/s ({times['stage2']:.1f} s)")
    for w in lin.warnings:
        echo(f"warning: {w}")


def _whole(cfg, records, start, out: Path, paths: dict, times: dict, echo) -> None:
    """The whole-model fit on ``records`` (from ``start``, a model, where given): ``whole.h5``."""
    from hwid.identify.whole import WholeModelFit
    t0 = time.perf_counter()
    res = WholeModelFit.from_config(cfg).fit(records, start=start).result_
    paths["whole"] = write_whole(out / "whole.h5", cfg, res)
    times["whole"] = time.perf_counter() - t0
    echo(f"whole model: {res.type}, d+ = {res.d_plus:.4g}, S^d = {res.slope_down:.4g}, d- = {res.d_minus:.4g}, "
         f"h degree {len(res.h_coefficients) - 1}, G {res.structure}, sigma {res.sigma:.4g} ({times['whole']:.1f} s)")
    for w in res.warnings:
        echo(f"warning: {w}")
