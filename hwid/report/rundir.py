"""Typed loading of a run directory for ``hwid report``.

:func:`load_run` reads whichever of these are present and notes what is missing:

=====================  =========================================================================
``simulation.h5``      the experiments (staircases, sines) and, for simulated plants, the truth
``nonlinear.h5``       stage 1 (:func:`hwid.results.read_nonlinear`)
``linear.h5``          stage 2 (:func:`hwid.results.read_linear`)
``batch.h5``           Monte Carlo summaries (:func:`hwid.results.read_batch_summary`)
``diagnosis.h5``       ``hwid diagnose`` (:func:`hwid.results.read_diagnosis`)
``compare.h5``         ``hwid compare`` (:func:`hwid.results.read_compare`)
``whole.h5``           the whole-model fit (:func:`hwid.results.read_whole`)
``history.h5``         stage 1 from a recorded history (:func:`hwid.results.read_history`)
=====================  =========================================================================

Every file is read through :mod:`hwid.results`; the stage results come back as the writers' own
types (:class:`~hwid.identify.result.NonlinearResult`, :class:`~hwid.identify.result.LinearResult`),
the batch summary and the diagnosis as the plain dicts their readers return. Nothing is estimated here.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hwid import HwidError, config, paper
from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PiecewiseH, PolynomialH
from hwid.identify.result import HistoryResult, LinearResult, NonlinearResult, WholeResult
from hwid.blocks.effects import EffectSpec
from hwid.model import Actuator, HWModel, InputNonlinearity, from_config
from hwid.plant import Record
from hwid.results import (ResultsError, open_results, read_batch_summary, read_compare, read_diagnosis, read_dict,
                          read_history, read_linear, read_nonlinear, read_records, read_whole)
from hwid.rundir import BATCH, COMPARE, DIAGNOSIS, FILES, HISTORY, IDENTIFICATION_JSON, LINEAR, NONLINEAR, SIMULATION, WHOLE

# The signals the figures draw: a staircase's input, output and undisturbed output; a sine's output
# and undisturbed output (its input, as long as its output, is not read). v, w, z are never read.
STAIRCASE_SIGNALS = ("u", "y", "x")
SINE_SIGNALS = ("y", "x")


@dataclass(frozen=True)
class RunData:
    """Everything the report shows, read from a run directory (plain data and stage results)."""

    directory: Path
    present: dict[str, bool]                      # file name -> present
    provenance: dict[str, dict]                   # file name -> root attributes
    cfg: config.Config | None = None              # the stored config, if it could be read again
    config_name: str | None = None
    records: dict[str, Record] = field(default_factory=dict)   # the experiments, by name
    truth: HWModel | None = None                  # normalised true model (simulated plants)
    nonlinear: NonlinearResult | None = None      # stage 1
    linear: LinearResult | None = None            # stage 2
    batch: dict | None = None                     # hwid.results.read_batch_summary(...)
    diagnosis: dict | None = None                 # hwid.results.read_diagnosis(...)
    compare: dict | None = None                   # hwid.results.read_compare(...)
    whole: WholeResult | None = None              # the whole-model fit
    history: HistoryResult | None = None          # stage 1 from a recorded history
    identification: dict | None = None            # identification.json: route, why, adequacy
    notes: tuple[str, ...] = ()                   # what is missing, what could not be shown

    @property
    def is_paper(self) -> bool:
        """True when the run used the paper's config: the report then shows the paper's columns."""
        return self.config_name == paper.CONFIG_NAME


def load_run(directory: str | Path) -> RunData:
    """Read a run directory. Raises :class:`hwid.HwidError` (one line) when ``directory`` is not a
    directory, holds no hwid results, or holds a file that is broken, foreign or from another config."""
    directory = Path(directory)
    present = _present_files(directory)
    notes: list[str] = []
    provenance = {name: _root_attributes(directory / name) for name in FILES if present[name]}
    cfg = _stored_config(directory, provenance, notes)
    config_name = cfg.name if cfg is not None else next(
        (p["config_name"] for p in provenance.values() if p.get("config_name")), None)

    records: dict[str, Record] = {}
    truth = None
    if present[SIMULATION]:
        records, truth = _read_simulation(directory / SIMULATION, notes)
    if truth is None and cfg is not None and cfg.plant.kind == "hammerstein_wiener":
        truth = from_config(cfg.plant).normalised()

    batch_only = (present[BATCH] or present[DIAGNOSIS] or present[COMPARE]) and not any(
        present[n] for n in FILES[:3])
    nonlinear = linear = None
    if present[NONLINEAR]:
        nonlinear = read_nonlinear(directory / NONLINEAR, cfg)
        records.update(_read_experiments(directory / NONLINEAR, "nonlinear", skip=set(records)))
    elif not batch_only:
        notes.append("nonlinear.h5 is missing: stage 1 (the input and output nonlinearities) has not "
                     "run here; run `hwid run` or the stage 1 command to get Table 1 and Figs. 9, 12")
    if present[LINEAR]:
        linear = read_linear(directory / LINEAR, cfg)
        records.update(_read_experiments(directory / LINEAR, "linear", skip=set(records)))
    elif not batch_only:
        notes.append("linear.h5 is missing: stage 2 (G(jω)) has not run here; Table 2 and the Bode "
                     "plot are not shown")
    if not present[SIMULATION] and not records and not batch_only:
        notes.append("simulation.h5 is missing: no measured experiments to plot")
    batch = read_batch_summary(directory / BATCH) if present[BATCH] else None
    diagnosis = None
    if present[DIAGNOSIS]:
        try:
            diagnosis = read_diagnosis(directory / DIAGNOSIS)
        except ResultsError as err:
            notes.append(f"diagnosis.h5 could not be read ({err})")
    compare = read_compare(directory / COMPARE) if present[COMPARE] else None
    whole = read_whole(directory / WHOLE, cfg) if present[WHOLE] else None
    history = read_history(directory / HISTORY, cfg) if present[HISTORY] else None
    identification = _read_identification(directory / IDENTIFICATION_JSON, notes)
    return RunData(directory, present, provenance, cfg, config_name, records, truth, nonlinear, linear,
                   batch, diagnosis, compare, whole, history, identification, tuple(notes))


def _read_identification(path: Path, notes: list) -> dict | None:
    """``hwid run``'s ``identification.json`` (route, why, adequacy), or None where absent or unreadable."""
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        notes.append(f"{path.name} could not be read ({type(err).__name__})")
        return None


def _present_files(directory: Path) -> dict[str, bool]:
    """Which of :data:`FILES` the directory holds; at least one, or :class:`hwid.HwidError`."""
    if not directory.exists():
        raise HwidError(f"{directory}: no such directory")
    if not directory.is_dir():
        raise HwidError(f"{directory}: not a directory (give the run directory that holds simulation.h5 ...)")
    present = {name: (directory / name).is_file() for name in FILES}
    if not any(present.values()):
        raise HwidError(f"{directory}: no hwid results here (expected one of {', '.join(FILES)})")
    return present


def _root_attributes(path: Path) -> dict:
    """The provenance attributes of a results file (:func:`hwid.results.write_provenance`), as
    Python values."""
    with open_results(path, path.stem) as f:
        out = {}
        for key, value in f.attrs.items():
            if isinstance(value, bytes):
                value = value.decode()
            elif isinstance(value, np.generic):
                value = value.item()
            out[key] = value
    return out


def _stored_config(directory: Path, provenance: dict[str, dict], notes: list[str]):
    """The config the files were written with (all must agree), read again; None when none stored
    it or it no longer reads (noted)."""
    texts = {n: p["config"] for n, p in provenance.items() if p.get("config")}
    hashes = {n: p["config_sha256"] for n, p in provenance.items() if p.get("config_sha256")}
    if len(set(hashes.values())) > 1:
        raise HwidError(f"{directory}: the results files come from different configs "
                        f"({', '.join(f'{n} {h[:12]}' for n, h in hashes.items())}); rerun the stages")
    if not texts:
        return None
    name, text = next(iter(texts.items()))
    try:
        return config.loads(text, source_path=f"{directory}/{name}:config")
    except HwidError as err:
        notes.append(f"the stored config could not be read again ({err}); truth and protocol "
                     "details from it are not shown")
        return None


def _read_simulation(path: Path, notes: list[str]) -> tuple[dict[str, Record], HWModel | None]:
    """The experiments of ``simulation.h5`` (the signals the figures draw) and its normalised truth."""
    truth = None
    with open_results(path, "simulation") as f:
        records = _experiments(f)
        if "truth" in f and "normalised" in f["truth"]:
            try:
                truth = _model_from_dict(read_dict(f["truth/normalised"]))
            except (KeyError, TypeError, ValueError) as err:
                notes.append(f"simulation.h5: the stored truth could not be read ({err})")
    return records, truth


def _read_experiments(path: Path, kind: str, skip: set[str]) -> dict[str, Record]:
    """The experiments a stage file stores (its ``experiments`` group), those in ``skip`` left out."""
    with open_results(path, kind) as f:
        return _experiments(f, skip)


def _experiments(f, skip: set[str] = frozenset()) -> dict[str, Record]:
    """The records of an open results file not named in ``skip``, in the file's order, with only
    the signals the figures draw (:data:`STAIRCASE_SIGNALS`, :data:`SINE_SIGNALS`)."""
    if "experiments" not in f:
        return {}
    group = f["experiments"]
    names = [n for n in group if n not in skip]
    sines = [n for n in names if n.startswith("sine_")]
    records = read_records(group, STAIRCASE_SIGNALS, [n for n in names if n not in sines])
    records.update(read_records(group, SINE_SIGNALS, sines))
    return {n: records[n] for n in names}


def _model_from_dict(d: dict) -> HWModel:
    """An :class:`hwid.model.HWModel` from ``HWModel.to_dict()`` as :func:`hwid.results.write_dict`
    stored it (the pieces of a piecewise h come back as a JSON list or a 2-D array)."""
    def floats(values):
        return tuple(float(c) for c in np.ravel(values))
    f, lin, out = d["input_nonlinearity"], d["linear"], d["output_nonlinearity"]
    if "polynomial" in out:
        h = PolynomialH(floats(out["polynomial"]))
    else:
        h = PiecewiseH(floats(out["breaks"]), tuple(floats(p) for p in out["pieces"]))
    return HWModel(InputNonlinearity(str(f["type"]), float(f["slope_up"]), float(f["slope_down"]),
                                     float(f["d_plus"]), float(f["d_minus"])),
                   LinearBlock(floats(lin["num"]), floats(lin["den"]), float(lin["delay"])),
                   h, Actuator.from_dict(d.get("actuator")), _effects_of(d.get("effects")))


def _effects_of(stored) -> tuple[EffectSpec, ...]:
    """The effects of ``HWModel.to_dict()`` as :func:`hwid.results.write_dict` stored them (a JSON
    list of ``{effect, PARAMETER: value}``); none where absent."""
    if not stored:
        return ()
    items = json.loads(stored) if isinstance(stored, str) else stored
    return tuple(EffectSpec(e["effect"], tuple((k, float(v)) for k, v in e.items() if k != "effect")) for e in items)
