"""The diagnosis's sim side: the model the plant is compared with.

Given by the user (``--model``: a plant YAML of kind ``hammerstein_wiener``, or a directory written
by ``hwid run``), or identified from the plant itself with the config's protocols (stage 1, stage 2
and the parametric G) when none is given. ``hwid compare`` reads its MODEL the same way.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import yaml

from hwid import HwidError, config
from hwid.identify.result import model_from_stages
from hwid.model import HWModel, from_config
from hwid.results import read_linear, read_nonlinear, read_whole, write_linear, write_nonlinear


def model_from_yaml(path: Path) -> HWModel:
    """The (un-normalised) model of a plant YAML, or of a config's ``plant``."""
    try:
        data = config.safe_yaml(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as err:
        raise HwidError(f"--model {path}: cannot read it ({type(err).__name__})") from None
    except yaml.YAMLError:
        raise HwidError(f"--model {path}: malformed YAML") from None
    if isinstance(data, dict) and "plant" in data:
        data = data["plant"]
    if not isinstance(data, dict):
        raise HwidError(f"--model {path}: expected a plant (kind: hammerstein_wiener) or a config with one")
    plant = config.parse_plant(data, f"--model {path}")
    if plant.kind != "hammerstein_wiener":
        raise HwidError(f"--model {path}: the model must be a plant of kind hammerstein_wiener, "
                        f"not {plant.kind}")
    return from_config(plant)


def model_from_run(path: Path, echo=print) -> tuple[HWModel, dict]:
    """The normalised model of a ``hwid run`` directory: its two stages' results, or, where it has
    none (a recorded plant's run), its whole-model fit (``whole.h5``)."""
    stages = all((path / name).exists() for name in ("nonlinear.h5", "linear.h5"))
    if not stages and (path / "whole.h5").exists():
        return read_whole(path / "whole.h5").model(), {"source": "results", "path": str(path), "fit": "whole",
                                                         "notes": []}
    for name in ("nonlinear.h5", "linear.h5"):
        if not (path / name).exists():
            raise HwidError(f"--model {path}: no {name} (nor whole.h5) in that directory (write them with 'hwid run')")
    nonlinear = read_nonlinear(path / "nonlinear.h5")
    notes: list = []
    model = model_from_stages(nonlinear, read_linear(path / "linear.h5"), notes)
    for note in notes:
        echo(note)
    return model, {"source": "results", "path": str(path), "w_range": [float(x) for x in nonlinear.w_range],
                   "notes": notes}


#: stage 2's sines shrink by this factor while their output rests on a sensor rail, at most
#: :data:`RAIL_TRIES` times (:func:`_sines_off_the_rails`)
RAIL_SHRINK = 0.7
RAIL_TRIES = 3


def identified_model(cfg, plant, out_dir=None, echo=print) -> tuple[HWModel, dict]:
    """Identify the model from ``plant`` with the config's staircases and sines (both stages); the
    results go to ``out_dir`` as ``nonlinear.h5`` and ``linear.h5``. The origin dict carries the
    identification's records (``records``), which the diagnosis uses and then drops."""
    from hwid.identify.deadzone_ahead import ThroughDeadZone, find_deadzone
    from hwid.identify.linear import identify_linear
    from hwid.identify.sine_runs import run_sines, unsafe_precompensator
    from hwid.identify.nonlinear import identify_nonlinear
    if cfg.protocols.staircase is None or cfg.protocols.sine is None:
        raise HwidError(f"{cfg.source_path}: without --model, diagnose identifies the model first and "
                        f"needs both protocols.staircase and protocols.sine")
    t0 = time.perf_counter()
    nonlinear, nonlinear_records = identify_nonlinear(cfg, plant=plant)
    ahead = find_deadzone(cfg, nonlinear, nonlinear_records)
    notes: list = []
    drive = plant        # what stage 2's sines go through: behind a dead zone, its inverse first
    if ahead is not None:
        echo(ahead.note())
        notes.append(ahead.note())
        nonlinear, drive = ahead.result, ThroughDeadZone(plant, ahead.delta)
    unsafe = unsafe_precompensator(cfg, nonlinear)
    if unsafe:
        # stage 1 did not identify F: the sines run as they are, for the whole fit below
        echo("stage 1 did not identify F: stage 2 is not run, and the sines drive the plant without a "
             "pre-compensator")
        _, linear_records = run_sines(cfg, None, plant=plant)
        records = [r for r in list(nonlinear_records) + list(linear_records) if r.y is not None]
        return _whole_instead(cfg, records, out_dir, unsafe, echo)
    linear, linear_records = identify_linear(cfg, nonlinear, plant=drive)
    cfg, linear, linear_records = _sines_off_the_rails(cfg, nonlinear, linear, linear_records, drive, echo)
    if ahead is not None:      # the records as the plant received them, for the diagnosis and the files
        linear_records = [drive.sent.get(r.name, r) for r in linear_records]
    if out_dir is not None:
        write_nonlinear(Path(out_dir) / "nonlinear.h5", cfg, nonlinear, nonlinear_records)
        write_linear(Path(out_dir) / "linear.h5", cfg, linear, linear_records)
    echo(f"identified the model ({time.perf_counter() - t0:.1f} s): {nonlinear.type}, d+ = {nonlinear.d_plus:.4g}, "
         f"d- = {nonlinear.d_minus:.4g}, S^d = {nonlinear.slope_down:.4g}, h degree {nonlinear.degree}, "
         f"G = {list(np.round(linear.parametric.get('num', []), 4))}/{list(np.round(linear.parametric.get('den', []), 4))}")
    levels = list(cfg.protocols.staircase.levels_up) + list(cfg.protocols.staircase.levels_down)
    records = [r for r in list(nonlinear_records) + list(linear_records) if r.y is not None]
    w_range = [float(x) for x in nonlinear.w_range]
    why = g_undetermined(linear)
    if why and out_dir is not None:
        return _whole_instead(cfg, records, out_dir, why, echo)
    stage_notes: list = []
    model = model_from_stages(nonlinear, linear, stage_notes)
    for note in stage_notes:
        echo(note)
    return model, {"source": "identified", "w_range": w_range, "notes": notes + stage_notes,
                   "u_range": [float(min(levels)), float(max(levels))], "records": records,
                   "input_deadzone_taken_out": ahead.delta if ahead is not None else 0.0}


def _sines_off_the_rails(cfg, nonlinear, linear, records, plant, echo):
    """Stage 2 again with sines :data:`RAIL_SHRINK` times as large, up to :data:`RAIL_TRIES` times,
    while its outputs rest on a sensor rail (:mod:`hwid.identify.rails`): a clipped output's
    harmonics are not those of ``h(G w)``, and G read from them is wrong where no effect's refit
    reaches it. The validation experiments still cover the staircases' range, where the clip is the
    diagnosis's to find. Returns the config whose sines were used, and stage 2's result and records."""
    from hwid.identify.rails import describe, find_rails
    from hwid.identify.linear import identify_linear
    for _ in range(RAIL_TRIES):
        found = find_rails([r.y for r in records if r.y is not None], [r.name for r in records if r.y is not None])
        if not found:
            break
        sine = cfg.protocols.sine.model_copy(update={"amplitude": RAIL_SHRINK * cfg.protocols.sine.amplitude})
        echo(f"stage 2's sines: {describe(found, cfg.sampling.dt)}; run again at amplitude {sine.amplitude:.3g}")
        cfg = cfg.model_copy(update={"protocols": cfg.protocols.model_copy(update={"sine": sine})})
        linear, records = identify_linear(cfg, nonlinear, plant=plant)
    return cfg, linear, records


def _whole_instead(cfg, records, out_dir, why: str, echo) -> tuple[HWModel, dict]:
    """The model fitted whole to the staircases and sines, with the input's slew rate, where the
    two stages cannot stand for the plant (``why``): the records still hold its response."""
    from hwid.diagnose.logs import identify_from_logs
    if out_dir is None:
        raise HwidError(f"{why}: the model cannot be identified in two stages")
    echo(f"{why}: the model is fitted whole to the staircases and sines, with the input's slew rate")
    model, origin = identify_from_logs(cfg, records, Path(out_dir), echo, rate_first=True)
    w = np.concatenate([model.input.apply(r.u) for r in records])   # the w the records reached
    return model, {**origin, "w_range": [float(w.min()), float(w.max())],
                   "notes": [why] + list(origin.get("notes", []))}


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


def load_model(spec, cfg=None, plant=None, out_dir=None, echo=print) -> tuple[HWModel, dict]:
    """The sim-side model and a description of where it came from.

    ``spec``: a YAML file, a ``hwid run`` directory, or None (identify it from ``plant`` with the
    config's protocols, :func:`identified_model`).
    """
    if spec is None:
        return identified_model(cfg, plant, out_dir, echo)
    path = Path(spec)
    if path.is_dir():
        return model_from_run(path, echo)
    if not path.exists():
        raise HwidError(f"--model {path}: no such file or directory")
    return model_from_yaml(path), {"source": "yaml", "path": str(path)}
