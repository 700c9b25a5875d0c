"""``hwid run``: the whole job on one plant — the model by the one identification path
(:func:`hwid.identify.path.identify`: staircases, stage 1, stage 2 behind the estimated
pre-compensator, or the whole-model fit where the stages cannot give a model), then the report.

One plant object serves every experiment, as on a rig: the simulated gear keeps its state, and an
external rig's calls are journalled in ``OUT/rig_journal`` so a rerun after a failure reuses them.
Writes ``OUT/simulation.h5`` (the staircases as measured, and the truth when the plant is
simulated; a recorded plant's records), ``OUT/nonlinear.h5`` and ``OUT/linear.h5`` (the stages),
``OUT/history.h5`` (stage 1 from a recorded plant's levels), ``OUT/whole.h5`` (the whole-model fit:
a recorded plant's model, a fallback's, or beside the stages with ``identification.whole.enabled``)
and ``OUT/report/``. Every run directory that ends with a model is a MODEL for ``hwid compare`` and
``hwid diagnose --model``.
"""
from __future__ import annotations

import time
from pathlib import Path

from hwid.plant import make_plant
from hwid.results import write_simulation
from hwid.results import write_json
from hwid.rundir import IDENTIFICATION_JSON, RIG_JOURNAL, SIMULATION


def run(cfg, out_dir: str | Path, report: bool = True, echo=print) -> dict:
    """Run everything; return the paths written, the seconds each step took, and the
    identification (:class:`hwid.identify.path.Identification`)."""
    from hwid.identify.path import identify
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    if cfg.plant.kind == "recorded":
        from hwid.recorded import load_records
        records = load_records(cfg)
        paths = {"simulation": write_simulation(out / SIMULATION, cfg, records, None)}
        ident = identify(cfg, records=records, out_dir=out, echo=echo)
    else:
        from hwid.simulate import truth
        plant = make_plant(cfg, journal_dir=out / RIG_JOURNAL)
        ident = identify(cfg, plant=plant, out_dir=out, echo=echo)
        paths = {"simulation": write_simulation(out / SIMULATION, cfg, ident.nonlinear_records, truth(cfg))}
    paths.update(ident.paths)
    times["identification"] = time.perf_counter() - t0
    echo(f"model: {ident.route} ({ident.why}; {times['identification']:.1f} s)")
    write_json(out / IDENTIFICATION_JSON, ident.to_dict())
    paths["identification"] = out / IDENTIFICATION_JSON
    if ident.adequacy is not None and ident.adequacy.verdict != "adequate":
        what = ("the model misses its records by more than the noise allows; its estimates above carry that "
                "misfit" if ident.adequacy.verdict == "misfit" else "the data cannot judge the model")
        echo(f"{ident.adequacy.verdict.upper()}: {what} ({ident.adequacy.reason})")
    if report:
        from hwid.report.html import write_report
        t0 = time.perf_counter()
        paths["report"] = write_report(out)
        times["report"] = time.perf_counter() - t0
        echo(f"report: {paths['report']} ({times['report']:.1f} s)")
    return {"paths": paths, "seconds": times, "identification": ident}
