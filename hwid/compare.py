"""``hwid compare``: a model's free-run simulation against measured experiments, like the System
Identification Toolbox's ``compare`` and ``resid``.

Each experiment is simulated from an initial state estimated from its own data: the gear's position
inside the play at the first sample and the level at which G is at rest (a record starts wherever
the rig was left, which the model cannot know). Then, per experiment and over all of them:

* the fit in percent, ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` (NRMSE fit of ``compare``);
* the RMS error, and the RMS error over the noise floor: a simulated plant's own noise, or for
  recorded data the floor estimated from the data alone (:func:`hwid.adequacy.estimate_floor`);
* the model's adequacy (:func:`hwid.adequacy.assess`, from the estimated initial states): ``misfit``
  where the RMS exceeds the floor by more than sampling variability allows;
* residual tests (``resid``): whiteness (Ljung-Box on the residual's autocorrelation) and
  correlation with past inputs (the cross-correlation's chi-square statistic), with their p-values
  (:func:`hwid.adequacy.residual_tests`, decimated so their lags span G's settling time: the same
  numbers as the figures and the adequacy verdict).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy import optimize

from hwid import HwidError
from hwid import adequacy
from hwid.adequacy import lag_step, residual_tests, settling_time
from hwid.model import HWModel


@dataclass(frozen=True)
class ExperimentFit:
    """One experiment's comparison; ``gear`` and ``rest`` are the estimated initial state."""

    name: str
    fit_percent: float
    rms: float
    samples: int
    gear: float
    rest: float
    whiteness_p: float
    input_correlation_p: float


@dataclass(frozen=True)
class CompareResult:
    """The comparison over all experiments; ``to_dict()`` is the ``--json`` output (fixed keys:
    ``fit_percent``, ``rms``, ``experiments`` [``name``, ``fit_percent``, ``rms``, ``samples``],
    ``residual`` [``whiteness_p``, ``input_correlation_p``], ``adequacy``
    (:meth:`hwid.adequacy.Adequacy.to_dict`, or None))."""

    fit_percent: float
    rms: float
    noise_floor: float | None
    experiments: tuple[ExperimentFit, ...]
    whiteness_p: float
    input_correlation_p: float
    model: dict
    adequacy: adequacy.Adequacy | None = None
    figures: tuple[str, ...] = ()      # the figures written, relative to the output folder
    lag_step: int = 1                  # the residual tests' decimation (:func:`hwid.adequacy.lag_step`)

    @property
    def rms_over_floor(self) -> float | None:
        return None if not self.noise_floor else self.rms / self.noise_floor

    def to_dict(self) -> dict:
        return {"fit_percent": self.fit_percent, "rms": self.rms, "noise_floor": self.noise_floor,
                "rms_over_floor": self.rms_over_floor,
                "experiments": [asdict(e) for e in self.experiments],
                "residual": {"whiteness_p": self.whiteness_p, "input_correlation_p": self.input_correlation_p,
                             "lag_step": self.lag_step},
                "model": self.model, "adequacy": None if self.adequacy is None else self.adequacy.to_dict(),
                "figures": list(self.figures)}


def fit_percent(y, y_hat) -> float:
    """NRMSE fit in percent: 100 means a perfect fit, 0 no better than the mean, negative worse."""
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    spread = np.linalg.norm(y - y.mean())
    if spread == 0:
        return 100.0 if np.allclose(y, y_hat) else float("-inf")
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / spread))


def initial_state(model: HWModel, u, y, dt: float, grid: int = 9) -> tuple[float, float, np.ndarray]:
    """The initial gear state and G's rest level that make the model's free run closest to ``y``
    (least squares: a ``grid x grid`` search, then Powell within the bounds). Returns
    ``(gear, rest, y_hat)``."""
    u, y = np.asarray(u, float), np.asarray(y, float)
    F, u_gear = model.at_the_gear(u, dt)       # the gear's band from what it receives (after a clip, a dead zone)
    lo, hi = F.start_band(u_gear)
    v_all = F.apply(u_gear)
    span = max(float(np.ptp(v_all)), hi - lo, 1e-9)
    rest_lo, rest_hi = float(v_all.min()) - 0.5 * span, float(v_all.max()) + 0.5 * span

    def cost(p):
        x = model.simulate(u, dt, gear=p[0], rest=p[1]).x
        r = y - x
        val = float(r @ r)
        return val if np.isfinite(val) else 1e300

    gears = np.linspace(lo, hi, grid) if hi > lo else np.array([lo])
    rests = np.linspace(rest_lo, rest_hi, grid)
    best = min(((g, r) for g in gears for r in rests), key=cost)
    if hi > lo:
        res = optimize.minimize(cost, np.array(best), method="Powell",
                                bounds=[(lo, hi), (rest_lo, rest_hi)], options={"xtol": 1e-6, "ftol": 1e-10})
        if res.fun <= cost(best):
            best = tuple(res.x)
    else:
        res = optimize.minimize_scalar(lambda r: cost((lo, r)), bounds=(rest_lo, rest_hi), method="bounded")
        best = (lo, float(res.x))
    return float(best[0]), float(best[1]), model.simulate(u, dt, gear=best[0], rest=best[1]).x


def compare_records(model: HWModel, records, noise_floor: float | None = None,
                    model_info: dict | None = None) -> tuple[CompareResult, dict]:
    """Compare ``model`` with every record; returns the result and ``{name: y_hat}``. ``noise_floor``
    None: estimated from the records (:func:`hwid.adequacy.estimate_floor`; left None where the data
    cannot determine it)."""
    if not records:
        raise HwidError("compare: the config yields no experiments to compare with")
    fits, sims = [], {}
    step = lag_step(records[0].dt, settling_time(model))
    ys, yhs, residuals = [], [], []
    for rec in records:
        gear, rest, y_hat = initial_state(model, rec.u, rec.y, rec.dt)
        residual = rec.y - y_hat
        white_p, input_p = residual_tests([residual], [rec.u], step)
        sims[rec.name] = y_hat
        ys.append(rec.y)
        yhs.append(y_hat)
        residuals.append(residual)
        fits.append(ExperimentFit(rec.name, fit_percent(rec.y, y_hat), float(np.sqrt(np.mean(residual ** 2))),
                                  int(rec.y.size), gear, rest, _p(white_p), _p(input_p)))
    white_p, input_p = residual_tests(residuals, [rec.u for rec in records], step)
    y_all, yh_all = np.concatenate(ys), np.concatenate(yhs)
    floor = floor_of(records, noise_floor)
    starts = {e.name: {"gear": e.gear, "rest": e.rest} for e in fits}
    judged = adequacy.assess(model, records, floor=floor, starts=starts, label="the records")
    result = CompareResult(fit_percent(y_all, yh_all), float(np.sqrt(np.mean((y_all - yh_all) ** 2))),
                           floor.sigma if floor.determined else None, tuple(fits),
                           _p(white_p), _p(input_p), dict(model_info or {}), judged, lag_step=step)
    return result, sims


def _p(p: float | None) -> float:
    """A p-value, NaN where the record was too short to test."""
    return float("nan") if p is None else float(p)


def floor_of(records, noise_floor: float | None) -> adequacy.NoiseFloor:
    """The noise floor the model is judged against: ``noise_floor`` where it is known (a simulated
    plant's noise), else estimated from the records alone."""
    if noise_floor:
        return adequacy.NoiseFloor(float(noise_floor), "known", 0.0, reason="the simulated plant's own noise")
    return adequacy.estimate_floor(records)


def experiments_of(cfg, out_dir: Path):
    """The experiments of ``cfg`` to compare with, and the noise floor where it is known: a
    recorded plant's records, or the config's protocols run on its plant (simulated or live; a
    live rig's calls are journalled in ``OUT/rig_journal``)."""
    from hwid.plant import make_plant
    from hwid.simulate import run_protocols
    if cfg.plant.kind == "recorded":
        from hwid.recorded import load_records
        return load_records(cfg), None
    records = run_protocols(cfg, make_plant(cfg, journal_dir=out_dir / "rig_journal"))
    floor = cfg.plant.noise.std if cfg.plant.kind == "hammerstein_wiener" and cfg.plant.noise.std > 0 else None
    return records, floor


def compare(model_spec, cfg, out_dir, json_path=None, echo=print) -> CompareResult:
    """``hwid compare MODEL CONFIG --out DIR``: writes ``DIR/compare.h5`` and ``DIR/compare.json``
    (or ``json_path``); returns the result."""
    from hwid.diagnose.sim_side import load_model
    from hwid.results import write_compare, write_json
    out = Path(out_dir)
    model, info = load_model(model_spec, echo=echo)
    records, floor = experiments_of(cfg, out)
    result, sims = compare_records(model, records, floor, {k: v for k, v in info.items() if k != "records"})
    from hwid.report.compare_figures import with_figures
    result = with_figures(result, out, model, records, sims)       # OUT/figures/compare_*.png
    write_compare(out / "compare.h5", cfg, result.to_dict(), records, sims)
    write_json(Path(json_path) if json_path else out / "compare.json", result.to_dict())
    for e in result.experiments:
        echo(f"{e.name}: fit {e.fit_percent:.2f} %, rms {e.rms:.4g} ({e.samples} samples)")
    tail = "" if result.rms_over_floor is None else f" = {result.rms_over_floor:.3g} x the noise floor"
    echo(f"overall: fit {result.fit_percent:.2f} %, rms {result.rms:.4g}{tail}; residual whiteness p = "
         f"{result.whiteness_p:.3g}, input correlation p = {result.input_correlation_p:.3g}")
    if result.adequacy is not None:
        floor = result.adequacy.floor
        echo(f"noise floor {floor.sigma:.4g} ({floor.source}: {floor.reason})")
        echo(f"adequacy: {result.adequacy.verdict}: {result.adequacy.reason}")
    return result


# the module is also the API's hwid.compare(model, data) (hwid.apinames)
from hwid.apinames import callable_as  # noqa: E402

callable_as(__name__, "compare")
