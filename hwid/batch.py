"""Monte Carlo batches: seeds, sweeps, executors, one writer.

* Seeds: run r of every sweep point uses child r of ``SeedSequence(cfg.seed).spawn(R)`` (common
  random numbers across sweep points), so results are identical whatever the number of workers or
  the executor.
* Executors: anything with the ``concurrent.futures.Executor`` interface. The default is a local
  process pool; ``--scheduler tcp://host:port`` uses ``distributed.Client(address).get_executor()``.
  hwid closes only the client it opened, never a cluster it did not create.
* One writer: workers return plain dicts; only the parent writes. Each finished run is appended to
  ``DIR/batch.jsonl`` (flushed and fsynced, one line per run), and ``DIR/batch.h5`` is rebuilt from
  the journal by an atomic rename every few seconds and at the end (the rebuild grows with the
  journal, so its interval grows too: at most ~4 % of the parent's time, which shares the cores with
  the workers). A SIGKILL at any moment loses at most the runs in flight (a torn last journal line is
  ignored); running the same command again computes only the missing runs.
* Threads: each local worker limits BLAS to one thread (J workers on J cores; a threaded BLAS
  inside each worker only oversubscribes them), with ``threadpoolctl`` when it is installed.
"""
from __future__ import annotations

import concurrent.futures as cf
import itertools
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hwid import HwidError
from hwid.progress import Progress
from hwid.results import write_batch
from hwid.rundir import BATCH
from hwid.threads import limit_blas_threads

SPEC = "batch_spec.json"
JOURNAL = "batch.jsonl"


# ----------------------------------------------------------------------------- sweeps

def parse_sweep(text: str) -> tuple[str, list]:
    """``"plant.noise.std=0.001,0.01"`` -> ``("plant.noise.std", [0.001, 0.01])`` (YAML scalars)."""
    import yaml
    key, sep, vals = text.partition("=")
    key = key.strip()
    if not sep or not key or not vals.strip():
        raise HwidError(f"--sweep {text!r}: expected KEY=V1,V2,... (e.g. plant.noise.std=0.001,0.01)")
    try:
        values = [yaml.safe_load(v) for v in vals.split(",")]
    except yaml.YAMLError:
        raise HwidError(f"--sweep {text!r}: cannot read the values") from None
    return key, values


def sweep_points(sweeps: list[tuple[str, list]]) -> list[dict]:
    """The cross product of the sweeps, as a list of ``{key: value}`` overrides."""
    if not sweeps:
        return [{}]
    keys = [k for k, _ in sweeps]
    return [dict(zip(keys, combo)) for combo in itertools.product(*[v for _, v in sweeps])]


# ----------------------------------------------------------------------------- one run

def truth_values(cfg) -> dict[str, float]:
    """The normalised true values (eqs. 4a-c) under the names used by :func:`flatten`."""
    from hwid.model import from_config
    if cfg.plant.kind != "hammerstein_wiener":
        return {}
    m = from_config(cfg.plant).normalised()
    out = {"slope_down": m.input.slope_down, "d_plus": m.input.d_plus, "d_minus": m.input.d_minus}
    coef = getattr(m.output, "coefficients", None)
    if coef is not None:
        for i, c in enumerate(coef):
            out[f"h_c{i}"] = float(c)
    if cfg.protocols.sine is not None:
        for w in cfg.protocols.sine.frequencies:
            g = m.linear.freqresp(w)
            out[f"gain@{w:g}"] = float(abs(g))
            out[f"phase@{w:g}"] = _phase(m.linear, w)
    return out


def _phase(lin, w) -> float:
    """phi(w) = -arg G(jw), continuous in w from 0 (Table 2 convention)."""
    grid = np.linspace(0, w, 512)[1:]
    return float(-np.unwrap(np.angle(lin.freqresp(grid)))[-1])


def flatten(nonlinear: dict | None, linear: dict | None) -> dict[str, float]:
    """Estimates, their 95 % intervals (``_lo``/``_hi``) and CRLBs as flat ``name -> float``."""
    out: dict[str, float] = {}
    if nonlinear:
        for k in ("slope_down", "d_plus", "d_minus"):
            if k in nonlinear:
                out[k] = float(nonlinear[k])
                ci = nonlinear.get(f"{k}_ci")
                if ci is not None:
                    out[k + "_lo"], out[k + "_hi"] = map(float, ci)
        coefs = nonlinear.get("h_coefficients") or []
        cis = nonlinear.get("h_coefficients_ci") or [None] * len(coefs)
        for i, (c, ci) in enumerate(zip(coefs, cis)):
            out[f"h_c{i}"] = float(c)
            if ci is not None:
                out[f"h_c{i}_lo"], out[f"h_c{i}_hi"] = map(float, ci)
        out["degree"] = float(nonlinear.get("degree", np.nan))
    if linear:
        for i, w in enumerate(linear.get("frequencies", [])):
            for q in ("gain", "phase"):
                out[f"{q}@{w:g}"] = float(linear[q][i])
                lo, hi = linear[f"{q}_ci"][i]
                out[f"{q}@{w:g}_lo"], out[f"{q}@{w:g}_hi"] = float(lo), float(hi)
                cr = linear.get(f"crlb_{q}")
                if cr is not None:
                    out[f"{q}@{w:g}_crlb"] = float(cr[i])
    return out


def run_once(cfg_text: str, seed: np.random.SeedSequence, stages: str = "both") -> dict:
    """One Monte Carlo run: a fresh noise realisation of the simulated plant, stage 1 then stage 2.

    Returns plain data: flat estimates and the seconds spent simulating vs estimating."""
    from hwid import config
    from hwid.identify.nonlinear import identify_nonlinear
    from hwid.plant import make_plant

    cfg = config.loads(cfg_text, source_path="<batch>")
    plant = _TimedPlant(make_plant(cfg, seed=seed))
    t0 = time.perf_counter()
    nl, _ = identify_nonlinear(cfg, plant=plant)
    lin = None
    if stages == "both" and cfg.protocols.sine is not None:
        from hwid.identify.linear import identify_linear
        lin, _ = identify_linear(cfg, nl, plant=plant)
    total = time.perf_counter() - t0
    return {"estimates": flatten(nl.to_dict(), lin.to_dict() if lin is not None else None),
            "seconds_simulate": plant.seconds, "seconds_estimate": total - plant.seconds}


class _TimedPlant:
    """Wraps a plant and accumulates the time spent inside it (simulation vs estimation split)."""

    def __init__(self, plant):
        self._plant = plant
        self.seconds = 0.0

    def __getattr__(self, name):
        return getattr(self._plant, name)

    def run(self, *a, **kw):
        t0 = time.perf_counter()
        try:
            return self._plant.run(*a, **kw)
        finally:
            self.seconds += time.perf_counter() - t0


def _task(args):
    point, run, cfg_text, seed = args
    t0 = time.perf_counter()
    try:
        res = run_once(cfg_text, seed)
    except HwidError as err:        # a run whose data defeat the estimator is a result, not a crash
        res = {"estimates": {}, "error": str(err)}
    res.update(point=point, run=run, seconds=time.perf_counter() - t0)
    return res


# ----------------------------------------------------------------------------- the batch

@dataclass
class BatchPlan:
    cfg: Any
    runs: int
    points: list[dict]
    configs: list[Any]

    def spec(self) -> dict:
        return {"config_sha256": self.cfg.sha256, "runs": self.runs, "points": self.points, "seed": self.cfg.seed}


def plan(cfg, runs: int, sweeps: list[tuple[str, list]]) -> BatchPlan:
    from hwid import config
    if runs < 1:
        raise HwidError("--runs must be at least 1")
    if cfg.plant.kind != "hammerstein_wiener":
        raise HwidError("hwid batch needs a simulated plant (plant.kind: hammerstein_wiener): a Monte Carlo "
                        "over noise realisations cannot drive a real rig")
    points = sweep_points(sweeps)
    configs = []
    for p in points:
        try:
            configs.append(config.with_overrides(cfg, p) if p else cfg)
        except config.ConfigError as err:
            raise HwidError(f"--sweep {p}: {str(err).split(': ', 1)[-1]}") from None
    return BatchPlan(cfg, runs, points, configs)


def read_journal(path: Path) -> list[dict]:
    """Finished runs in the journal; a torn last line (killed mid-write) is ignored."""
    out = []
    if not path.exists():
        return out
    with open(path, "rb") as fh:
        for line in fh:
            try:
                out.append(json.loads(line))
            except (json.JSONDecodeError, UnicodeDecodeError):
                continue
    return out


def run_batch(cfg, runs: int, out_dir: str | Path, sweeps: list[tuple[str, list]] | None = None,
              jobs: int = 1, scheduler: str | None = None, executor: cf.Executor | None = None,
              progress: bool | None = None, flush_seconds: float = 2.0) -> Path:
    """Run (or resume) a batch; return the path of ``batch.h5``."""
    bp = plan(cfg, runs, sweeps or [])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec_path, jpath = out / SPEC, out / JOURNAL
    spec = bp.spec()
    if spec_path.exists():
        old = json.loads(spec_path.read_text())
        if old != json.loads(json.dumps(spec)):
            raise HwidError(f"{out}: holds a different batch (config, runs or sweeps differ); use another --out")
    else:
        tmp = spec_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(spec, indent=1))
        os.replace(tmp, spec_path)
    done = {(r["point"], r["run"]) for r in read_journal(jpath)}
    seeds = np.random.SeedSequence(cfg.seed).spawn(runs)
    todo = [(i, r, c.source_text, seeds[r]) for i, c in enumerate(bp.configs) for r in range(runs)
            if (i, r) not in done]
    own = None
    if executor is None:
        if scheduler:
            try:
                from distributed import Client
            except ImportError:
                raise HwidError("--scheduler needs the optional extra: pip install 'hwid[dask]'") from None
            try:
                own = Client(scheduler, timeout="10s")
            except OSError as err:
                raise HwidError(f"--scheduler {scheduler}: cannot connect ({err})") from None
            executor = own.get_executor()
        else:
            own = executor = cf.ProcessPoolExecutor(max_workers=max(1, jobs), initializer=limit_blas_threads)
    last = time.monotonic()
    interval = flush_seconds
    try:
        with open(jpath, "ab") as jf, Progress(len(bp.points) * runs, "batch", "runs", enabled=progress) as bar:
            bar.update(len(bp.points) * runs - len(todo))
            futures = [executor.submit(_task, t) for t in todo]
            for fut in cf.as_completed(futures):
                res = fut.result()
                jf.write((json.dumps(res, default=float) + "\n").encode())
                jf.flush()
                os.fsync(jf.fileno())
                bar.update()
                if time.monotonic() - last > interval:
                    t0 = time.monotonic()
                    write_batch_h5(out, bp)
                    last = time.monotonic()
                    interval = max(flush_seconds, 25 * (last - t0))
    finally:
        if own is not None:
            if isinstance(own, cf.Executor):
                own.shutdown(wait=True, cancel_futures=True)
            else:
                own.close()          # closes our client only; the cluster keeps running
    return write_batch_h5(out, bp)


# ----------------------------------------------------------------------------- summaries and the file

def summarise(results: list[dict], truth: dict[str, float]) -> dict[str, dict]:
    """Bias, std, RMSE, interval coverage and CRLB efficiency per estimate (runs without errors).
    ``coverage`` is over the runs whose estimate has an interval; ``without_interval`` counts the
    others (a parameter fixed by the normalisation, or one a run's data left undetermined)."""
    ok = [r["estimates"] for r in results if r.get("estimates")]
    stats: dict[str, dict] = {}
    for name, true in truth.items():
        vals = np.array([e[name] for e in ok if name in e], float)
        if vals.size == 0:
            continue
        s: dict[str, float] = {"truth": true, "n": int(vals.size), "mean": float(vals.mean()),
                               "bias": float(vals.mean() - true),
                               "std": float(vals.std(ddof=1)) if vals.size > 1 else float("nan"),
                               "rmse": float(np.sqrt(np.mean((vals - true) ** 2)))}
        lo = np.array([e.get(name + "_lo", np.nan) for e in ok if name in e])
        hi = np.array([e.get(name + "_hi", np.nan) for e in ok if name in e])
        # a run without an interval (fixed by the normalisation, or undetermined) is neither covered
        # nor missed: the coverage is over the runs with one, and the others are counted
        has = np.isfinite(lo) & np.isfinite(hi)
        s["without_interval"] = int(np.sum(~has))
        if np.any(has):
            s["coverage"] = float(np.mean((lo[has] <= true) & (true <= hi[has])))
        cr = np.array([e.get(name + "_crlb", np.nan) for e in ok if name in e])
        if np.all(np.isfinite(cr)):
            s["crlb_std"] = float(np.sqrt(np.mean(cr)))
            s["efficiency"] = float(np.mean(cr) / s["std"] ** 2) if s["std"] > 0 else float("nan")
        stats[name] = s
    return stats


def write_batch_h5(out: Path, bp: BatchPlan) -> Path:
    """Rebuild ``batch.h5`` from the journal (layout in :func:`hwid.results.write_batch`)."""
    results = read_journal(out / JOURNAL)
    points = []
    for i, (p, c) in enumerate(zip(bp.points, bp.configs)):
        rs = sorted((r for r in results if r["point"] == i), key=lambda r: r["run"])
        columns = {"run": np.array([r["run"] for r in rs], int),
                   "seconds": np.array([r.get("seconds", np.nan) for r in rs])}
        for key in ("seconds_simulate", "seconds_estimate"):
            columns[key] = np.array([r.get(key, np.nan) for r in rs])
        for name in sorted({k for r in rs for k in r["estimates"]}):
            columns[name] = np.array([r["estimates"].get(name, np.nan) for r in rs])
        points.append({"overrides": p, "columns": columns, "summary": summarise(rs, truth_values(c)),
                       "errors": [r["error"] for r in rs if r.get("error")]})
    return write_batch(out / BATCH, bp.cfg, bp.runs, points)
