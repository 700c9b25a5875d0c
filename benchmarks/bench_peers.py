"""hwid side by side with what users would pick instead, on the same data (issue 16).

For each simulated plant, two identification data sets of equal rig time:

* ``hwid protocol``: hwid's own staircases and sines through the true pre-compensator (Fig. 8);
* ``peer design``: random steps with random holds and a chirp, what a NARX or OE user records.

Every method is fitted on each set and judged on the same held-out records that no method saw (a
random multilevel input with random holds, a sine sweep at another amplitude, a triangle), by its
free-run simulation error (never one-step-ahead): RMS and RMS over the noise sigma. Methods:

* ``hwid stages``: the paper's two stages with the parametric G(s) (hwid protocol only: they need it);
* ``hwid whole``: the whole-model output-error fit (started from the stages where they ran);
* ``NARX (FROLS)``: a polynomial NARX by FROLS (sysidentpy), degree 3, lags 2, BIC, as a careful
  user would start;
* ``linear OE``: the best linear approximation, an output-error model with a first- or second-order G;
* ``nlhw analogue``: the same output-error fit with hwid's F replaced by a static dead zone (what
  MATLAB's ``nlhw`` offers for play): what memory in the input block is worth;
* ``truth``: the true plant without noise (the floor).

Then the STS3215 servo logs (``../shared/data/real/sts3215/``, skipped where the folder is absent):
for every log and motor under test, every method is fitted on one half of the log as recorded and
judged by free-run RMS (counts) on the other half, both ways round: over every sample, and over the
samples where both puller servos are relaxed (their pushes move the output through the play while
the target holds, a load no method here has an input for). There is no truth there; the encoder's
quantum alone leaves ``1/sqrt(12)`` count. ``hwid corrected`` is the diagnosis's product: ``hwid
diagnose --model`` of the ``hwid whole`` model on the fitting half alone, its ``corrected.yaml``
(that model with the verdict's effect added) run free on the other half like the rest; its column
names each half's verdict, with the gap before and after against the noise floor.

sysidentpy pins an older numpy, so the peers get a virtual environment of their own:
``python3.11 -m venv .venv-peers && .venv-peers/bin/pip install -e '.[peers]'``; then
``.venv-peers/bin/python benchmarks/bench_peers.py [PLANT ... | sts] [--write]`` prints the tables (every plant and the STS3215 logs when none is named).
``--write`` replaces the tables of docs/validation/peers.md (``docs/validation/generated/peers_*.md``)
with those measured in this call. ``--hwid-only`` leaves the peers and the simulated plants out:
hwid's columns on the STS3215 logs (``hwid whole``, ``from stage 1``, ``hwid corrected``) in any
environment with hwid installed.
"""
from __future__ import annotations

import os
import platform
import sys
import time
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from scipy import optimize  # noqa: E402

from hwid import HwidError, config  # noqa: E402
from hwid.compare import compare_records  # noqa: E402
from hwid.identify.linear import ExtrapolationWarning, identify_linear  # noqa: E402
from hwid.identify.nonlinear import identify_nonlinear  # noqa: E402
from hwid.identify.result import model_from_stages  # noqa: E402
from hwid.identify.whole import Structure, WholeModelFit, g_from_params, g_params_from  # noqa: E402
from hwid.model import HWModel, from_config  # noqa: E402
from hwid.plant import Record, SimulatedPlant  # noqa: E402

SIGMA = 0.01
PLANTS = {
    "paper": {"input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.5, "d_minus": -0.5},
              "linear": {"num": [0.2], "den": [1.0, 0.7, 0.1]},
              "output_nonlinearity": {"polynomial": [0, 0.25, 0, -0.42, 0, 0.2]}},
    "asymmetric": {"input_nonlinearity": {"type": "backlash", "slope_up": 1.2, "slope_down": 0.8, "d_plus": 0.4, "d_minus": -0.2},
                   "linear": {"num": [2.25], "den": [1.0, 0.9, 2.25]},
                   "output_nonlinearity": {"polynomial": [0, 1.0, 0.25]}},
    "backlash-inverse": {"input_nonlinearity": {"type": "backlash_inverse", "slope_up": 1.0, "slope_down": 1.1,
                                                "d_plus": 0.2, "d_minus": -0.1},
                         "linear": {"num": [1.0], "den": [1.0, 1.0]},
                         "output_nonlinearity": {"polynomial": [0, 1.0, 0.3, -0.5]}},
}
DT = 0.05


def plant_config(name: str) -> config.Config:
    p = PLANTS[name]
    return config.loads(yaml.safe_dump({
        "name": f"peers-{name}", "seed": 11, "sampling": {"dt": DT},
        "plant": {"kind": "hammerstein_wiener", **p, "noise": {"std": SIGMA}},
        "protocols": {"staircase": {"levels_up": [-1.2, -0.9, -0.6, -0.3, 0.0, 0.3, 0.6, 0.9, 1.2],
                                    "levels_down": [0.9, 0.6, 0.3, 0.0, -0.3, -0.6, -0.9, -1.2], "hold": 30.0},
                      "sine": {"amplitude": 1.0, "frequencies": [0.05, 0.1, 0.2, 0.5, 1.0], "periods": 6,
                               "lead_in_periods": 2}},
        "identification": {"nonlinear": {"max_degree": 5}}}))


def random_steps(rng, seconds: float, lo=-1.3, hi=1.3, hold=(2.0, 20.0)) -> np.ndarray:
    u = []
    while len(u) * DT < seconds:
        u += [rng.uniform(lo, hi)] * int(rng.uniform(*hold) / DT)
    return np.array(u[:int(seconds / DT)])


def chirp(seconds: float, amplitude: float, w0: float, w1: float) -> np.ndarray:
    t = np.arange(int(seconds / DT)) * DT
    phase = w0 * t + (w1 - w0) * t * t / (2 * seconds)
    return amplitude * np.sin(phase)


def triangle(seconds: float, amplitude: float, period: float) -> np.ndarray:
    t = np.arange(int(seconds / DT)) * DT
    return amplitude * (2 * np.abs(2 * (t / period - np.floor(t / period + 0.5))) - 1)


def validation_records(truth, rng) -> list[Record]:
    inputs = {"random_levels": random_steps(rng, 400.0, hold=(3.0, 25.0)),
              "sweep": chirp(400.0, 0.8, 0.02, 1.5),
              "triangle": triangle(300.0, 1.1, 60.0)}
    return [Record(name, DT, u, truth.simulate(u, DT).x + SIGMA * rng.standard_normal(u.size))
            for name, u in inputs.items()]


# --------------------------------------------------------------------------------- the peers

def fit_narx(records):
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares
    u = np.concatenate([r.u for r in records])[:, None]
    y = np.concatenate([r.y for r in records])[:, None]
    model = FROLS(order_selection=True, ylag=2, xlag=2, info_criteria="bic", n_info_values=30,
                  estimator=LeastSquares(), basis_function=Polynomial(degree=3))
    model.fit(X=u, y=y)

    def simulate(rec):
        with np.errstate(all="ignore"):
            out = model.predict(X=rec.u[:, None], y=rec.y[:model.max_lag, None])[:, 0]
        return np.where(np.isfinite(out), out, 1e3)
    return simulate


class _OutputError:
    """Output-error fit of ``y = h(G * F(u))`` with a static F (identity, or a dead zone) and a
    polynomial h (solved for), G of unit gain from :func:`hwid.identify.whole.g_from_params`."""

    def __init__(self, structure: Structure, degree: int, dead_zone: bool):
        self.structure, self.degree, self.dead_zone = structure, degree, dead_zone

    def _w(self, theta, u, dt):
        n_g = self.structure.n_params
        g = g_from_params(self.structure, theta[:n_g])
        if self.dead_zone:
            d_plus, d_minus = theta[n_g], theta[n_g] - np.exp(theta[n_g + 1])
            u = np.where(u > d_plus, u - d_plus, np.where(u < d_minus, u - d_minus, 0.0))
        return g.simulate(u, dt)

    def _design(self, w):
        return np.vander(w, self.degree + 1, increasing=True)

    def fit(self, records):
        y = np.concatenate([r.y for r in records])

        def residual(theta):
            w = np.concatenate([self._w(theta, r.u, r.dt) for r in records])
            if not np.all(np.isfinite(w)):
                return np.full(y.size, 1e3)
            phi = self._design(w)
            return y - phi @ np.linalg.lstsq(phi, y, rcond=None)[0]
        span = max(r.u.size * r.dt for r in records)
        theta0 = list(g_params_from(self.structure, None, span, records[0].dt))
        if self.dead_zone:
            theta0 += [0.2, np.log(0.4)]
        best = optimize.least_squares(residual, np.array(theta0), x_scale=1.0, max_nfev=300)
        self.theta = best.x
        w = np.concatenate([self._w(best.x, r.u, r.dt) for r in records])
        self.coef = np.linalg.lstsq(self._design(w), y, rcond=None)[0]
        return self

    def simulate(self, rec):
        return self._design(self._w(self.theta, rec.u, rec.dt)) @ self.coef


def fit_output_error(records, dead_zone: bool):
    """The better of a first- and a second-order G (BIC), h of degree 5 (linear OE: degree 1)."""
    degree = 5 if dead_zone else 1
    fits = []
    y = np.concatenate([r.y for r in records])
    for structure in (Structure(1, 0), Structure(0, 1)):
        model = _OutputError(structure, degree, dead_zone).fit(records)
        rss = float(sum(np.sum((r.y - model.simulate(r)) ** 2) for r in records))
        k = structure.n_params + degree + 1 + 2 * dead_zone
        fits.append((y.size * np.log(rss / y.size) + k * np.log(y.size), model))
    return min(fits, key=lambda f: f[0])[1].simulate


# --------------------------------------------------------------------------------- the runs

def hwid_protocol_records(cfg, truth):
    plant = SimulatedPlant(truth, DT, SIGMA, seed=np.random.SeedSequence(5))
    nl, nl_records = identify_nonlinear(cfg, plant=plant)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExtrapolationWarning)
            lin, lin_records = identify_linear(cfg, nl, plant=plant)
    except HwidError as err:       # stage 2 refuses a pre-compensator stage 1 did not identify
        return list(nl_records), None, " ".join(str(err).split())
    return list(nl_records) + list(lin_records), model_from_stages(nl, lin), ""


def judge(simulate_or_model, validation, sigma: float = SIGMA) -> float:
    """RMS over ``sigma`` of the free run on the validation records (hwid models from their
    estimated initial state, as ``hwid compare`` does)."""
    if hasattr(simulate_or_model, "simulate") and hasattr(simulate_or_model, "input"):
        result, _ = compare_records(simulate_or_model, validation)
        return result.rms / sigma
    errors = np.concatenate([r.y - simulate_or_model(r) for r in validation])
    return float(np.sqrt(np.mean(errors ** 2))) / sigma


def run_plant(name: str) -> list[tuple]:
    cfg = plant_config(name)
    truth = from_config(cfg.plant)
    validation = validation_records(truth, np.random.default_rng(99))
    rows = [(name, "-", "truth (floor)", judge(truth, validation), 0.0, "nothing")]
    t0 = time.perf_counter()
    protocol, stages, refused = hwid_protocol_records(cfg, truth)
    t_stages = time.perf_counter() - t0
    rig_seconds = sum(r.u.size for r in protocol) * DT
    peer = [Record("steps", DT, u, truth.simulate(u, DT).x + SIGMA * np.random.default_rng(7).standard_normal(u.size))
            for u in (random_steps(np.random.default_rng(3), 0.7 * rig_seconds),)]
    sweep = chirp(0.3 * rig_seconds, 1.0, 0.02, 1.5)
    peer.append(Record("chirp", DT, sweep, truth.simulate(sweep, DT).x + SIGMA * np.random.default_rng(8).standard_normal(sweep.size)))
    rows.append((name, "hwid protocol", "hwid stages", judge(stages, validation) if stages is not None else float("nan"),
                 t_stages, "none (protocol from the config)" if stages is not None else f"refused: {refused[:90]}"))
    from hwid.identify.whole import fit_records
    for design, records, start in (("hwid protocol", fit_records(protocol), stages), ("peer design", peer, None)):
        t0 = time.perf_counter()
        whole = WholeModelFit(max_degree=5, structures=[Structure(1, 0), Structure(2, 0), Structure(0, 1)]).fit(
            records, start=start).result_.model()
        rows.append((name, design, "hwid whole", judge(whole, validation), time.perf_counter() - t0, "none"))
        for method, fit, tuned in (("NARX (FROLS)", fit_narx, "degree 3, lags 2"),
                                   ("linear OE", lambda r: fit_output_error(r, False), "G order 1-2"),
                                   ("nlhw analogue", lambda r: fit_output_error(r, True), "dead zone, h degree 5, G order 1-2")):
            t0 = time.perf_counter()
            try:
                rows.append((name, design, method, judge(fit(records), validation), time.perf_counter() - t0, tuned))
            except Exception as err:  # noqa: BLE001 - a peer that fails is reported, not hidden
                rows.append((name, design, method, float("nan"), time.perf_counter() - t0, f"failed: {err}"))
    print(f"  {name}: {rig_seconds:.0f} rig-seconds per design", flush=True)
    return rows


# --------------------------------------------------------------------------------- the STS3215 logs

STS_FOLDER = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "sts3215"


def sts_halves(path: Path, stand) -> tuple[list[Record], list[np.ndarray], config.Config]:
    """The log of the motor under test (target in, position out, counts about its home) as two
    halves, each with the mask of its samples where both pullers are relaxed (at their relaxed
    target and within 4 counts of it, as ``experiments/real/sts3215.py: relaxed`` reads them)."""
    from hwid.recorded import load_records

    def channel(motor: int, offset: int) -> dict:
        return {"file": str(path), "time": {"column": "timestamp"},
                "input": {"column": f"target pos ({motor})", "offset": -offset},
                "output": {"column": f"pos ({motor})", "offset": -offset}}
    base = {"name": f"sts-{path.stem}-{stand.dut}", "sampling": {"dt": 0.1},
            "plant": {"kind": "recorded", "experiments": [channel(stand.dut, stand.home)]},
            "identification": {"whole": {"enabled": True, "max_order": 2}}}
    cfg = config.loads(yaml.safe_dump(base))
    (whole,) = load_records(cfg)
    relaxed = np.ones(whole.u.size, bool)
    for motor, p in stand.pullers.items():
        base["plant"]["experiments"] = [channel(motor, p["relaxed"])]
        (puller,) = load_records(config.loads(yaml.safe_dump(base)))
        relaxed &= (puller.u[:whole.u.size] == 0) & (np.abs(puller.y[:whole.u.size]) <= 4)
    half = whole.u.size // 2
    return ([Record("first half", whole.dt, whole.u[:half], whole.y[:half]),
             Record("second half", whole.dt, whole.u[half:], whole.y[half:])],
            [relaxed[:half], relaxed[half:]], cfg)


def judge_counts(simulate_or_model, record: Record, relaxed: np.ndarray) -> tuple[float, float]:
    """Free-run RMS (counts) on a held-out half: over every sample, and over the relaxed ones."""
    if hasattr(simulate_or_model, "simulate") and hasattr(simulate_or_model, "input"):
        _, sims = compare_records(simulate_or_model, [record])
        y_hat = sims[record.name]
    else:
        y_hat = simulate_or_model(record)
    with np.errstate(all="ignore"):
        err = record.y - y_hat
        return float(np.sqrt(np.mean(err ** 2))), float(np.sqrt(np.mean(err[relaxed] ** 2)))


def sts_whole(cfg, records, staged: bool) -> HWModel:
    """hwid's whole-model fit as ``hwid run`` does it (``staged``: as ``hwid diagnose`` on logs
    does, the borders started from stage 1 on the records' levels where they hold enough)."""
    from hwid.identify.history import identify_recorded
    from hwid.model import InputNonlinearity
    borders = None
    if staged:
        try:
            hist = identify_recorded(cfg, records)
            borders = InputNonlinearity(hist.type, 1.0, hist.slope_down, hist.d_plus, hist.d_minus)
        except HwidError:
            pass
    return WholeModelFit.from_config(cfg, staged=staged).fit(records, borders=borders).result_.model()


def sts_corrected(cfg, record: Record, verdicts: list) -> HWModel:
    """The corrected simulator of ``hwid diagnose --model`` on ``record`` alone: hwid's whole fit of
    ``record`` (:func:`sts_whole`, the ``hwid whole`` column's model) saved as a run directory, the
    diagnosis of it on a recorded config of a copy of ``record`` (it splits the record into blocks,
    fits each catalogue effect on some and scores it on the others), and its ``corrected.yaml``: that
    model with the verdict's effect added at its fitted parameters, or as it was for ``none`` and
    ``unexplained``. (Identified by the diagnosis itself, a half's fit blocks hold too few levels.)
    The verdict, its gap before and after and the noise floor are appended to ``verdicts``."""
    import tempfile

    from hwid.diagnose import diagnose
    from hwid.diagnose.sim_side import load_model
    from hwid.results import write_whole
    quiet = lambda *a, **k: None  # noqa: E731
    result = WholeModelFit.from_config(cfg, staged=False).fit([record]).result_
    with tempfile.TemporaryDirectory() as tmp:
        csv, run = Path(tmp) / "half.csv", Path(tmp) / "run"
        np.savetxt(csv, np.column_stack([record.u, record.y]), delimiter=",", header="target,pos", comments="")
        half = config.loads(yaml.safe_dump({
            "name": "sts-half", "sampling": {"dt": float(record.dt)},
            "plant": {"kind": "recorded", "experiments": [{"file": str(csv), "input": {"column": "target"},
                                                           "output": {"column": "pos"}}]}}))
        run.mkdir()
        write_whole(run / "whole.h5", cfg, result, "model")
        s = diagnose(half, Path(tmp) / "diag", model=str(run), echo=quiet)
        verdicts.append((s["verdict"]["effect"], s["gap_before"], s["gap_after"], s["noise_floor"]))
        model, _ = load_model(str(Path(tmp) / "diag" / "corrected.yaml"), echo=quiet)
    return model


def _verdicts_note(verdicts: list) -> str:
    return "diagnosis: " + "; ".join(f"{v} (gap {b:.3g} -> {a:.3g}, floor {f:.3g})" for v, b, a, f in verdicts)


def sts_rows(hwid_only: bool = False) -> list[tuple]:
    """Every log and motor under test: each method fitted on one half, judged on the other, both
    ways round; the mean RMS (counts) over the two held-out halves, all samples and relaxed ones."""
    import pandas as pd
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "real"))
    from sts3215 import stands
    rows = []
    for path in sorted(STS_FOLDER.glob("motor_telemetry_*.csv")):
        for stand in stands(pd.read_csv(path)):
            halves, relaxed, cfg = sts_halves(path, stand)
            name = f"{path.stem.removeprefix('motor_telemetry_')} (motor {stand.dut})"
            verdicts: list = []
            methods = (("hwid whole", lambda r: sts_whole(cfg, r, False), "none"),
                       ("hwid whole, from stage 1", lambda r: sts_whole(cfg, r, True), "none"),
                       ("hwid corrected", lambda r: sts_corrected(cfg, r[0], verdicts), "none"),
                       ("NARX (FROLS)", fit_narx, "degree 3, lags 2"),
                       ("linear OE", lambda r: fit_output_error(r, False), "G order 1-2"),
                       ("nlhw analogue", lambda r: fit_output_error(r, True), "dead zone, h degree 5, G order 1-2"))
            for method, fit, tuned in methods[:3] if hwid_only else methods:
                scores, seconds = [], 0.0
                for k in (0, 1):
                    t0 = time.perf_counter()
                    try:
                        model = fit([halves[k]])
                        seconds += time.perf_counter() - t0
                        scores.append(judge_counts(model, halves[1 - k], relaxed[1 - k]))
                    except Exception as err:  # noqa: BLE001 - a method that fails is reported, not hidden
                        seconds += time.perf_counter() - t0
                        tuned = f"failed: {err}"
                        scores.append((float("nan"), float("nan")))
                rms_all, rms_relaxed = np.mean(scores, axis=0)
                if method == "hwid corrected" and verdicts:
                    tuned = f"{tuned}; {_verdicts_note(verdicts)}"
                rows.append((name, method, rms_all, rms_relaxed, seconds / 2, tuned))
            print(f"  {name}: {halves[0].u.size} + {halves[1].u.size} samples, "
                  f"{int(relaxed[0].sum() + relaxed[1].sum())} relaxed", flush=True)
    return rows


def _number(x: float) -> str:
    return "diverged" if not np.isfinite(x) or x > 1e6 else f"{x:.3g}"


def pivot(rows: list[tuple], keys: int, value) -> str:
    """A markdown table with one row per the first ``keys`` fields of ``rows`` and one column per
    method (in the order met); ``value(row)`` is the cell's text."""
    methods = list(dict.fromkeys(r[keys] for r in rows))
    cells: dict[tuple, dict[str, str]] = {}
    for r in rows:
        cells.setdefault(tuple(r[:keys]), {})[r[keys]] = value(r)
    head = ["plant", "data"] if keys == 2 else ["log (motor)"]
    lines = ["| " + " | ".join(head + methods) + " |", "|---" * (len(head) + len(methods)) + "|"]
    for k, by in cells.items():
        lines.append("| " + " | ".join([*k, *(by.get(m, "–") for m in methods)]) + " |")
    return "\n".join(lines)


def write_pages(rows: list[tuple], sts: list[tuple]) -> None:
    """The docs page's two tables as fragments: RMS over sigma on the simulated plants; RMS in
    counts (every sample / pullers relaxed) on the STS3215 logs."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
    from fragment import write
    env = f"numpy {np.__version__} in the peers' environment"
    if rows:
        # the truth's row (design "-") becomes a column beside every design of its plant
        truth = {r[0]: r for r in rows if r[1] == "-"}
        sim = [r for r in rows if r[1] != "-"]
        sim += [(p, d, *truth[p][2:]) for p, d in dict.fromkeys((r[0], r[1]) for r in sim) if p in truth]
        md = (f"Held-out free-run RMS / σ (1.0 is the floor); {env}.\n\n"
              + pivot(sim, 2, lambda r: "refused" if str(r[5]).startswith("refused") else _number(r[3])))
        print(f"wrote {write('peers_simulated', md, 'benchmarks/bench_peers.py')}")
    if sts:
        md = (f"Mean held-out free-run RMS in counts, every sample / pullers relaxed; the encoder's quantum alone "
              f"leaves {1 / np.sqrt(12):.2f}; {env}.\n\n" + pivot(sts, 1, lambda r: f"{_number(r[2])} / {_number(r[3])}"))
        print(f"wrote {write('peers_sts', md, 'benchmarks/bench_peers.py')}")


def main():
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"numpy {np.__version__}")
    write_it = "--write" in sys.argv[1:]
    hwid_only = "--hwid-only" in sys.argv[1:]
    only = set(sys.argv[1:]) - {"--write", "--hwid-only"}     # plant names, or "sts"; none: all of them
    if write_it and hwid_only:
        sys.exit("--write needs the peers' columns too: run it without --hwid-only, in .venv-peers")
    rows = []
    for name in PLANTS:
        if (not only or name in only) and not hwid_only:
            rows += run_plant(name)
    sts = []
    if not only or "sts" in only:
        if STS_FOLDER.is_dir():
            sts = sts_rows(hwid_only)
        else:
            print(f"  STS3215 logs skipped: {STS_FOLDER} is absent")
    if rows:
        print("\n| plant | data | method | RMS / sigma (held out, free run) | fit s | tuned by hand |")
        print("|---|---|---|---|---|---|")
        for plant, design, method, ratio, seconds, tuned in rows:
            print(f"| {plant} | {design} | {method} | {_number(ratio)} | {seconds:.1f} | {tuned} |")
    if sts:
        print(f"\nSTS3215 logs: fitted on one half, free run on the other, both ways round (mean); counts; "
              f"the encoder's quantum alone leaves {1 / np.sqrt(12):.2f}")
        print("| log (motor) | method | RMS, every sample | RMS, pullers relaxed | fit s | tuned by hand |")
        print("|---|---|---|---|---|---|")
        for log, method, rms_all, rms_relaxed, seconds, tuned in sts:
            print(f"| {log} | {method} | {_number(rms_all)} | {_number(rms_relaxed)} | {seconds:.1f} | {tuned} |")
    if write_it:
        write_pages(rows, sts)


if __name__ == "__main__":
    main()
