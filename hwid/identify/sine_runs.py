"""Stage 2's experiments on the plant (paper Section 5, Fig. 8): the config's sines (eq. 15), each
driven through the pre-compensator built from stage 1's estimate, and the guard that keeps a
pre-compensator stage 1 could not build from ever driving the plant
(:func:`unsafe_precompensator`). :mod:`hwid.identify.linear` reads G from their records.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from hwid import HwidError


@lru_cache(maxsize=2)
def _sines(amplitude: float, frequencies: tuple, periods: int, lead_in_periods: int, dt: float) -> tuple:
    """:func:`hwid.protocols.sines` of a config, computed once per process (a Monte Carlo batch
    runs the same sines every run: 6e6 samples of eq. 15 for the paper config); read only."""
    from hwid import protocols
    out = tuple(protocols.sine(amplitude, w, periods, lead_in_periods, dt, name=f"sine_{i}")
                for i, w in enumerate(frequencies))
    for s in out:
        s.t.flags.writeable = False
        s.z.flags.writeable = False
    return out


def input_span(cfg, amplitude: float) -> tuple[float, float]:
    """The inputs a pre-compensated sine may ask of the plant: the staircases' range (the inputs
    stage 1 was identified on) widened by its width on either side, which holds any pre-compensator
    of a play and slopes stage 1 can estimate from those levels; without staircases, the sine's own
    range widened likewise."""
    st = cfg.protocols.staircase
    levels = list(st.levels_up) + list(st.levels_down) if st is not None else [-amplitude, amplitude]
    lo, hi = float(min(levels)), float(max(levels))
    return lo - (hi - lo), hi + (hi - lo)


def _config_sines(cfg) -> list:
    """The sines of ``cfg.protocols.sine`` (:func:`_sines`)."""
    sn = cfg.protocols.sine
    return list(_sines(float(sn.amplitude), tuple(float(w) for w in sn.frequencies), int(sn.periods),
                       int(sn.lead_in_periods), float(cfg.sampling.dt)))


def _inputs(cfg, nonlinear, sines) -> list[np.ndarray]:
    """Each sine's input to the plant: through the pre-compensator built from ``nonlinear``, or the
    sine itself where ``nonlinear`` is None."""
    if nonlinear is None:
        return [np.array(s.z, float) for s in sines]
    F, kind = nonlinear.input_nonlinearity(), cfg.identification.linear.precompensator
    with np.errstate(all="ignore"):
        return [F.precompensator(s.z, kind) for s in sines]


def _why_unsafe(cfg, nonlinear, sines, inputs) -> str:
    """:func:`unsafe_precompensator` of the ``inputs`` already built for ``sines``."""
    if nonlinear is None:
        return ""
    lo, hi = input_span(cfg, float(cfg.protocols.sine.amplitude))
    for s, u in zip(sines, inputs):
        if not (np.all(np.isfinite(u)) and lo <= u.min() and u.max() <= hi):
            return (f"the pre-compensator built from stage 1 (S^d = {nonlinear.slope_down:.3g}, d+ = "
                    f"{nonlinear.d_plus:.3g}, d- = {nonlinear.d_minus:.3g}) asks the plant for inputs "
                    f"{np.nanmin(u):.3g} to {np.nanmax(u):.3g} on {s.name}, beyond [{lo:.3g}, {hi:.3g}]")
    return ""


def unsafe_precompensator(cfg, nonlinear) -> str:
    """Why the pre-compensator built from stage 1's ``nonlinear`` must not drive the plant, or ``""``:
    on some sine of ``cfg`` it asks for inputs that are not finite or lie beyond
    :func:`input_span`. A stage 1 that did not identify F (levels that never settled under a slow
    actuator gave S^d = 5e21) builds one that would command the rig 1e21 units."""
    if cfg.protocols.sine is None or nonlinear is None:
        return ""
    sines = _config_sines(cfg)
    try:
        inputs = _inputs(cfg, nonlinear, sines)
    except ValueError as err:   # stage 1's F has no pre-compensator (its borders cross once inverted)
        return (f"no pre-compensator can be built from stage 1 (S^d = {nonlinear.slope_down:.3g}, d+ = "
                f"{nonlinear.d_plus:.3g}, d- = {nonlinear.d_minus:.3g}): {err}")
    return _why_unsafe(cfg, nonlinear, sines, inputs)


def run_sines(cfg, nonlinear, plant=None, journal_dir=None, progress: bool | None = None):
    """Drive the plant with each sine of ``cfg`` through the pre-compensator built from ``nonlinear``
    (Fig. 8); return ``(sines, records)``. ``nonlinear=None``: the sines themselves, with no
    pre-compensator (the whole-model fit's records where stage 1 is unusable). A pre-compensator
    that would drive the plant beyond :func:`input_span` raises :class:`HwidError` before any sine
    runs (:func:`unsafe_precompensator`)."""
    from hwid.plant import make_plant
    from hwid.progress import Progress
    if cfg.protocols.sine is None:
        raise HwidError(f"{cfg.source_path}: protocols.sine is missing; stage 2 needs the sine experiments")
    sines = _config_sines(cfg)
    inputs = _inputs(cfg, nonlinear, sines)
    why = _why_unsafe(cfg, nonlinear, sines, inputs)
    if why:
        raise HwidError(f"{why}: stage 1 did not identify F (see its warnings); the plant is not driven with it")
    plant = plant if plant is not None else make_plant(cfg, journal_dir=journal_dir)
    how = "none" if nonlinear is None else "estimated"
    records = []
    with Progress(sum(s.z.size for s in sines), "identify-linear", "samples", enabled=progress) as bar:
        for s, u in zip(sines, inputs):
            r = plant.run(s.name, u, z=s.z)
            r.attrs.update({"omega": s.omega, "amplitude": s.amplitude, "periods": s.periods,
                            "lead_in_periods": s.lead_in_periods, "precompensator": how,
                            "precompensator_kind": cfg.identification.linear.precompensator})
            records.append(r)
            bar.update(s.z.size)
    return sines, records
