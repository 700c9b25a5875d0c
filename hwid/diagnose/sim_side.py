"""The diagnosis's sim side: the model the plant is compared with.

Given by the user (``--model``: a plant YAML of kind ``hammerstein_wiener``, or a directory written
by ``hwid run``), or identified from the plant itself by the one identification path
(:func:`hwid.identify.path.identify`) when none is given. ``hwid compare`` reads its MODEL the same
way. An identified model's actuator (a clip, a slew rate, a dead zone ahead of F) is handed to its
effect as a start where the model without it still describes its records, and kept in the
baseline where it does not (:func:`diagnosis_baseline`).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import yaml

from hwid import HwidError, config
from hwid.identify.path import g_undetermined  # noqa: F401  (where the diagnosis's tests look for it)
from hwid.model import HWModel, from_config
from hwid.results import read_linear, read_nonlinear, read_whole, whole_role
from hwid.rundir import LINEAR, NONLINEAR, WHOLE


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
    """The normalised model of a ``hwid run`` directory, as that run identified it: its whole-model
    fit (``whole.h5``) where the run's model is that fit (a recorded plant's, or the fallback where
    the stages could not give one), else its two stages' results (with the input dead zone stage 1
    was identified behind)."""
    from hwid.identify.path import stages_model
    whole = path / WHOLE
    stages = all((path / name).exists() for name in (NONLINEAR, LINEAR))
    if whole.exists() and (not stages or whole_role(whole) == "model"):
        res = read_whole(whole)
        return res.model(), {"source": "results", "path": str(path), "fit": "whole", "notes": [],
                             "starts": dict(res.initial_states)}
    for name in (NONLINEAR, LINEAR):
        if not (path / name).exists():
            raise HwidError(f"--model {path}: no {name} (nor whole.h5) in that directory (write them with 'hwid run')")
    nonlinear = read_nonlinear(path / NONLINEAR)
    notes: list = []
    model = stages_model(nonlinear, read_linear(path / LINEAR), notes)
    for note in notes:
        echo(note)
    return model, {"source": "results", "path": str(path), "w_range": [float(x) for x in nonlinear.w_range],
                   "notes": notes}


def identified_model(cfg, plant, out_dir=None, echo=print) -> tuple[HWModel, dict]:
    """Identify the model from ``plant`` by the one identification path
    (:func:`hwid.identify.path.identify`; its results go to ``out_dir``), and take it as the
    diagnosis's baseline (:func:`diagnosis_baseline`). The origin dict carries the identification's
    records (``records``), which the diagnosis uses and then drops."""
    from hwid.identify.path import identify
    if cfg.protocols.staircase is None or cfg.protocols.sine is None:
        raise HwidError(f"{cfg.source_path}: without --model, diagnose identifies the model first and "
                        f"needs both protocols.staircase and protocols.sine")
    t0 = time.perf_counter()
    ident = identify(cfg, plant=plant, out_dir=out_dir, echo=echo)
    echo(f"identified the model ({time.perf_counter() - t0:.1f} s) by the {ident.route} route: {ident.why}")
    return origin_of(ident, echo)


def origin_of(ident, echo=print) -> tuple[HWModel, dict]:
    """The diagnosis's baseline model and its origin from an identification
    (:class:`hwid.identify.path.Identification`)."""
    model, taken, notes = diagnosis_baseline(ident.model, ident.records, ident.starts, echo)
    origin = {"source": "identified", "route": ident.route, "route_why": ident.why,
              "notes": list(ident.notes) + notes, "records": list(ident.records),
              "u_range": list(ident.u_range) if ident.u_range else None, **taken}
    if ident.route == "whole":
        origin.update({"fit": "whole", "starts": dict(ident.starts)})
    if ident.w_range is not None:
        origin["w_range"] = list(ident.w_range)
    if ident.adequacy is not None:
        origin["adequacy"] = ident.adequacy.to_dict()
    return model, origin


def free_run_explodes(model: HWModel, records, starts: dict | None = None) -> str:
    """Why ``model``'s free run on ``records`` cannot stand for them, or ``""``: it is not finite,
    or its RMS error exceeds the output's own spread (its standard deviation about its mean: a
    model that does worse than the output's mean describes nothing of it). Each record from its
    start in ``starts`` (``{name: {"gear", "rest"}}``, the whole fit's) where given."""
    starts = starts or {}
    res, ys = [], []
    for r in records:
        if r.y is None or not r.u.size:
            continue
        st = starts.get(r.name, {})
        with np.errstate(all="ignore"):
            x = model.simulate(r.u, r.dt, gear=st.get("gear"), rest=st.get("rest"), position=st.get("position")).x
        res.append(np.asarray(r.y, float) - x)
        ys.append(np.asarray(r.y, float))
    if not res:
        return ""
    e, y = np.concatenate(res), np.concatenate(ys)
    if not np.all(np.isfinite(e)):
        return "its free run on its records is not finite"
    rms, spread = float(np.sqrt(np.mean(e * e))), float(np.std(y))
    if rms > spread:
        return f"its free run misses its records by an RMS of {rms:.4g}, above the output's own spread {spread:.4g}"
    return ""


def diagnosis_baseline(model: HWModel, records, starts: dict | None, echo=print) -> tuple[HWModel, dict, list]:
    """The model the diagnosis measures effects against, the origin's keys that say so, and notes.

    The actuator the identification fitted ahead of F (:class:`hwid.model.Actuator`) is taken out
    and handed to its effect as a start (``input_clip_taken_out``, ``input_rate_taken_out``,
    ``input_deadzone_taken_out``; :func:`hwid.diagnose.run.actuator_hints`), which must earn it back
    on the validation part:

    * a clip or a slew rate the whole fit found, where the model without it still describes its
      records (:func:`free_run_explodes`). Where it does not (an h fitted behind a clip to
      [-0.60, 0.13] and run without it reached coefficients of 1e11 and a noise floor of 1e9 on a
      damper log), the baseline is the complete fitted model, and ``baseline`` says why;
    * a dead zone stage 1 found behind which its levels fit (:mod:`hwid.identify.deadzone_ahead`,
      with its own interval and consistency test) always: F, G and h were identified behind it, and
      the diagnosis's validation experiments stay within the staircases' range. Where the model
      without it misses its records, a note says by how much (the paper's plant behind a dead zone
      of 0.2: an RMS of 2.5 on records of spread 1.07, h of degree 5 driven beyond where it was
      identified by the dead zone's inverse), and ``input_deadzone`` is named from it as before."""
    act = model.actuator
    if act is None:
        return model, {}, []
    bare = model.without_actuator()
    why = free_run_explodes(bare, records, starts)
    fitted_whole = act.clip is not None or act.rate is not None
    if why and fitted_whole:
        note = (f"the model without its actuator ({_actuator_text(act)}): {why}; the diagnosis's baseline is the "
                "complete fitted model, actuator included")
        echo(note)
        return model, {"baseline": "complete", "baseline_why": note}, [note]
    notes = []
    if why:
        notes.append(f"the model without its {_actuator_text(act)}: {why}; the dead zone is left to input_deadzone, "
                     "started at its width")
        echo(notes[-1])
    return bare, {"baseline": "actuator taken out", "input_rate_taken_out": act.rate or 0.0,
                  "input_clip_taken_out": list(act.clip) if act.clip else None,
                  "input_deadzone_taken_out": float(act.deadzone)}, notes


def _actuator_text(act) -> str:
    """The actuator's blocks in words."""
    parts = [f"clip [{act.clip[0]:.4g}, {act.clip[1]:.4g}]"] if act.clip else []
    parts += [f"slew {act.rate:.4g} units/s"] if act.rate else []
    parts += [f"dead zone {act.deadzone:.4g}"] if act.deadzone else []
    return ", ".join(parts)


def check_diagnosable(model: HWModel, origin: dict, dt: float) -> None:
    """Raise :class:`HwidError` (one line) where a given model carries effects the diagnosis's
    blocks cannot hold (:func:`hwid.diagnose.modelsim.folded`)."""
    from hwid.diagnose.modelsim import folded
    try:
        folded(model, dt)
    except ValueError as err:
        raise HwidError(f"--model {origin.get('path', '')}: {err}") from None


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
