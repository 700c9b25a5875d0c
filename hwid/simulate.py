"""``hwid simulate``: run the config's protocols on its plant and store every experiment.

Staircases (eqs. 6, 13) are applied as they are. Sines (eq. 15) go through the pre-compensator of
the *true* input nonlinearity (Fig. 8) when the plant is simulated, and are applied bare to an
external plant (whose nonlinearity is unknown until stage 1 has run); the ``precompensator``
attribute of each sine group says which.
"""
from __future__ import annotations

from pathlib import Path

from hwid import protocols
from hwid.model import from_config
from hwid.plant import SimulatedPlant, make_plant
from hwid.progress import Progress
from hwid.results import write_simulation
from hwid.rundir import RIG_JOURNAL, SIMULATION


def truth(cfg) -> dict | None:
    """The plant's true model and its normalised form (eqs. 4a-c), or None for an external plant."""
    if cfg.plant.kind != "hammerstein_wiener":
        return None
    m = from_config(cfg.plant)
    return {"model": m.to_dict(), "normalised": m.normalised().to_dict()}


def run_protocols(cfg, plant=None, progress: bool | None = None):
    """Run the staircases and sines of ``cfg`` on ``plant``; return the records."""
    plant = plant or make_plant(cfg)
    exps = []
    if cfg.protocols.staircase is not None:
        exps += [(s.name, s.u, None, {"direction": s.direction, "hold": s.hold,
                                        "levels": s.levels.tolist(), "lead_in": s.lead_in.tolist()})
                 for s in protocols.staircases(cfg)]
    if cfg.protocols.sine is not None:
        for s in protocols.sines(cfg):
            if isinstance(plant, SimulatedPlant):
                u, pre = plant.model.input.precompensator(s.z, cfg.identification.linear.precompensator), "true"
            else:
                u, pre = s.z, "none"
            exps.append((s.name, u, s.z, {"omega": s.omega, "amplitude": s.amplitude, "periods": s.periods,
                                          "lead_in_periods": s.lead_in_periods, "precompensator": pre}))
    records = []
    with Progress(sum(e[1].size for e in exps), "simulate", "samples", enabled=progress) as bar:
        for name, u, z, attrs in exps:
            r = plant.run(name, u, z=z)
            r.attrs.update(attrs)
            records.append(r)
            bar.update(u.size)
    return records


def simulate(cfg, out_dir: str | Path, progress: bool | None = None) -> Path:
    """Write ``OUT/simulation.h5`` (layout in docs/guide/outputs.md): the protocols run on the plant, or a
    recorded plant's records read, cleaned and resampled (:mod:`hwid.recorded`)."""
    out = Path(out_dir) / SIMULATION
    if cfg.plant.kind == "recorded":
        from hwid.recorded import load_records
        return write_simulation(out, cfg, load_records(cfg), None)
    records = run_protocols(cfg, make_plant(cfg, journal_dir=Path(out_dir) / RIG_JOURNAL), progress)
    return write_simulation(out, cfg, records, truth(cfg))
