"""Stage 2 efficiency: Monte Carlo variance of |G_hat| and phi_hat against the Cramer-Rao bound.

For the paper's plant (configs/paper.yaml: h_bar of eq. 30c, G_bar of eq. 30b, U = 1, sigma = 0.01)
at each of Table 2's frequencies, the noise-free response behind the exact pre-compensator is
simulated once (zero-order hold included) and ``--runs`` independent white Gaussian noise
realisations are added. Both estimators see the true normalised h (the bound assumes h known).

Efficiency = CRLB / Monte Carlo variance (1 = efficient); its 95 % interval reflects the finite
number of runs. Coverage = fraction of runs whose 95 % interval holds the truth.

Moderate settings by default (dt = 0.05 s, 10 periods after 1 lead-in period, 1000 runs):

    .venv/bin/python benchmarks/bench_stage2_efficiency.py [--runs 1000] [--dt 0.05] [--periods 10] [--write]

``--write`` replaces the table of docs/validation/crlb.md (``docs/validation/generated/crlb.md``).
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import stats

from hwid import config, protocols
from hwid.identify.crlb import crlb
from hwid.identify.known import KnownNonlinear
from hwid.identify.linear import ExtrapolationWarning, LinearEstimator
from hwid.model import from_config
from hwid.plant import Record, SimulatedPlant

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from fragment import write  # noqa: E402


def run(runs: int = 1000, dt: float = 0.05, periods: int = 10, lead_in: int = 1, seed: int = 20240611):
    cfg = config.load(ROOT / "configs" / "paper.yaml")
    model = from_config(cfg.plant)
    truth = model.normalised()
    nl = KnownNonlinear.from_config(cfg)
    sigma = cfg.plant.noise.std
    U = cfg.protocols.sine.amplitude
    plant = SimulatedPlant(model, dt, 0.0, 0.0, 0)
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    rows = []
    for w in cfg.protocols.sine.frequencies:
        s = protocols.sine(U, w, periods, lead_in, dt)
        u = truth.input.precompensator(s.z)
        x = plant.run(f"sine_{w}", u).y
        G = truth.linear.freqresp(w)
        g0, p0 = abs(G), -np.angle(G)
        est = {"nls": [], "paper": []}
        t0 = time.perf_counter()
        n_used = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExtrapolationWarning)
            for _ in range(runs):
                y = x + sigma * rng.standard_normal(x.size)
                e = LinearEstimator().fit(Record("s", dt, u, y), s, nl)
                n_used = e.harmonics_.n_samples
                for m in est:
                    r = e.estimates_[m]
                    est[m].append((r["gain"], r["phase"], *r["gain_ci"], *r["phase_ci"]))
        sec = (time.perf_counter() - t0) / runs
        kappa = abs((1 - np.exp(-1j * w * dt)) / (1j * w * dt))
        vg, vp = crlb(nl.h_coefficients, U, g0, p0, sigma, n_used, input_gain=kappa)
        row = {"omega": w, "n": n_used, "crlb_sd_gain": np.sqrt(vg), "crlb_sd_phase": np.sqrt(vp), "sec": sec}
        lo, hi = stats.chi2.ppf([0.025, 0.975], runs - 1) / (runs - 1)
        for m, a in est.items():
            a = np.asarray(a)
            a[:, 1] = p0 + np.angle(np.exp(1j * (a[:, 1] - p0)))
            for j, (name, t, v) in enumerate((("gain", g0, vg), ("phase", p0, vp))):
                var = a[:, j].var(ddof=1)
                row[f"{m}_eff_{name}"] = v / var
                row[f"{m}_eff_{name}_ci"] = (v / var * lo, v / var * hi)
                row[f"{m}_bias_{name}"] = a[:, j].mean() - t
                row[f"{m}_cov_{name}"] = float(np.mean((a[:, 2 + 2 * j] <= t) & (t <= a[:, 3 + 2 * j])))
        rows.append(row)
    return rows


def table(rows, runs, dt, periods) -> str:
    head = (f"Stage 2 efficiency (CRLB / Monte Carlo variance), paper plant, U = 1, sigma = 0.01, dt = {dt} s, "
            f"{periods} periods, {runs} runs\n\n"
            "| omega (rad/s) | samples | CRLB sd |G| | CRLB sd phi | nls eff |G| | nls eff phi | "
            "paper eff |G| | paper eff phi | nls coverage |G| / phi | paper coverage |G| / phi | ms/run |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|\n")
    lines = []
    for r in rows:
        f = lambda m, q: f"{r[f'{m}_eff_{q}']:.2f} [{r[f'{m}_eff_{q}_ci'][0]:.2f}, {r[f'{m}_eff_{q}_ci'][1]:.2f}]"  # noqa: E731
        lines.append(f"| {r['omega']:g} | {r['n']} | {r['crlb_sd_gain']:.2e} | {r['crlb_sd_phase']:.2e} | "
                     f"{f('nls', 'gain')} | {f('nls', 'phase')} | {f('paper', 'gain')} | {f('paper', 'phase')} | "
                     f"{r['nls_cov_gain']:.3f} / {r['nls_cov_phase']:.3f} | "
                     f"{r['paper_cov_gain']:.3f} / {r['paper_cov_phase']:.3f} | {1e3 * r['sec']:.1f} |")
    return head + "\n".join(lines)


def page(rows, runs, dt, periods) -> str:
    """The docs page's table: efficiencies with their 95 % intervals, and the coverages with the
    Monte Carlo error of a coverage (two binomial standard deviations at 0.95)."""
    mc = 2 * np.sqrt(0.95 * 0.05 / runs)
    f = lambda r, m, q: f"{r[f'{m}_eff_{q}']:.2f} [{r[f'{m}_eff_{q}_ci'][0]:.2f}, {r[f'{m}_eff_{q}_ci'][1]:.2f}]"  # noqa: E731
    lines = [f"{runs} Monte Carlo runs at each frequency; dt = {dt} s, {periods} periods after 1 lead-in, "
             f"σ = 0.01, U = 1. Efficiency = CRLB / Monte Carlo variance with its 95 % interval (1 is the "
             f"bound); a coverage's Monte Carlo error is ±{mc:.3f} (2 sd of a binomial at 0.95).", "",
             "| ω (rad/s) | samples | nls eff. \\|G\\| | nls eff. φ | paper eq. (37) eff. \\|G\\| | paper eff. φ | "
             "nls coverage \\|G\\| / φ | paper coverage \\|G\\| / φ |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['omega']:g} | {r['n']} | {f(r, 'nls', 'gain')} | {f(r, 'nls', 'phase')} | "
                     f"{f(r, 'paper', 'gain')} | {f(r, 'paper', 'phase')} | "
                     f"{r['nls_cov_gain']:.3f} / {r['nls_cov_phase']:.3f} | "
                     f"{r['paper_cov_gain']:.3f} / {r['paper_cov_phase']:.3f} |")
    eff = [r[f"nls_eff_{q}"] for r in rows for q in ("gain", "phase")]
    cov = [r[f"nls_cov_{q}"] for r in rows for q in ("gain", "phase")]
    pap = [r[f"paper_eff_{q}"] for r in rows for q in ("gain", "phase")]
    lines += ["", f"nls efficiencies {min(eff):.2f}–{max(eff):.2f}, its coverages {min(cov):.3f}–{max(cov):.3f}; "
                  f"the paper's estimator's efficiencies {min(pap):.2f}–{max(pap):.2f}."]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--dt", type=float, default=0.05)
    ap.add_argument("--periods", type=int, default=10)
    ap.add_argument("--write", action="store_true", help="write the docs page's table (docs/validation/generated/crlb.md)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    rows = run(a.runs, a.dt, a.periods)
    print(table(rows, a.runs, a.dt, a.periods))
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    if a.write:
        print(f"wrote {write('crlb', page(rows, a.runs, a.dt, a.periods), 'benchmarks/bench_stage2_efficiency.py')}")


if __name__ == "__main__":
    main()
