"""Command line: thin. Each command parses its arguments, calls one library function, and turns
known errors (:class:`hwid.HwidError`) into one line on stderr and exit code 2."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from hwid import HwidError, __version__
from hwid.rundir import HISTORY, NONLINEAR

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Identify Hammerstein-Wiener systems with Backlash / Backlash-Inverse input "
                       "(Brouri et al.). See README.md.")


def _version(value: bool):
    if value:
        typer.echo(f"hwid {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    pass


def _out_dir(out: Path) -> Path:
    if out.exists() and not out.is_dir():
        raise HwidError(f"--out {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise HwidError(f"--out {out}: cannot create the directory ({err.strerror or type(err).__name__})") from None
    return out


@app.command()
def check(config: Path = typer.Argument(..., help="Config YAML to validate.")):
    """Validate a config and exit (0 if it is usable, 2 with one line if not)."""
    from hwid.config import load as load_config
    cfg = load_config(config)
    detail, splits = "", []
    if cfg.plant.kind == "external":
        from hwid.plant import load_external
        load_external(cfg)   # imports the named callable (only that) and checks its signature
    elif cfg.plant.kind == "recorded":
        from hwid.recorded import describe, load_records, split_lines
        records = load_records(cfg)                        # reads every file, writes nothing
        detail, splits = "; " + describe(records), split_lines(records)
    typer.echo(f"{config}: OK ({cfg.name}, plant {cfg.plant.kind}, config sha256 {cfg.sha256[:12]}){detail}")
    for line in splits:
        typer.echo(line)


@app.command()
def simulate(config: Path = typer.Argument(..., help="Config YAML."),
             out: Path = typer.Option(..., "--out", help="Output directory (simulation.h5 goes here).")):
    """Run the config's staircases and sines on its plant; write OUT/simulation.h5."""
    from hwid.config import load as load_config
    from hwid.simulate import simulate as run
    cfg = load_config(config)
    path = run(cfg, _out_dir(out))
    typer.echo(f"wrote {path}")


class _Said:
    """The path's lines as a command prints them: warnings on stderr, the rest on stdout; what was
    said is remembered so the command's own summary does not repeat it."""

    def __init__(self):
        self.lines: set[str] = set()

    def __call__(self, line: str) -> None:
        self.lines.add(line)
        typer.echo(line, err=line.startswith("warning: "))

    def warnings(self, messages) -> None:
        for msg in messages:
            if f"warning: {msg}" not in self.lines and msg not in self.lines:
                self(f"warning: {msg}")


@app.command("identify-linear")
def identify_linear(config: Path = typer.Argument(..., help="Config YAML."),
                    nonlinear: Path = typer.Option(..., "--nonlinear", help="Stage 1 result DIR/nonlinear.h5 "
                                                   "(a recorded plant: DIR/history.h5)."),
                    out: Path = typer.Option(..., "--out", help="Output directory (linear.h5 goes here)."),
                    json_out: Optional[Path] = typer.Option(None, "--json", help="Also write the result as JSON.")):
    """Stage 2 (Section 5): sines behind the estimated pre-compensator, G(jw), a rational G(s); OUT/linear.h5.
    For a recorded plant: from its steady periodic stretches, pre-compensated or not. The same step
    'hwid run' takes (hwid.identify.path.stage2)."""
    from hwid.config import load as load_config
    from hwid import results
    from hwid.identify.path import g_undetermined, stage2
    cfg = load_config(config)
    out = _out_dir(out)
    said = _Said()
    if cfg.plant.kind == "recorded":    # the records' periodic stretches, with stage 1 from history.h5
        from hwid.recorded import load_records
        hist = results.read_history(nonlinear / HISTORY if nonlinear.is_dir() else nonlinear, cfg)
        two = stage2(cfg, hist, records=load_records(cfg), out_dir=out, echo=said)
        if two.linear is None:
            raise HwidError(f"{config}: stage 2 from periodic stretches: {two.why}; 'hwid run' fits the whole "
                            "model to the records instead")
    else:
        nl = results.read_nonlinear(nonlinear / NONLINEAR if nonlinear.is_dir() else nonlinear, cfg)
        two = stage2(cfg, nl, out_dir=out, echo=said)
        if two.linear is None:
            raise HwidError(f"{config}: {two.why}: stage 1 did not identify F, so stage 2 is not run; "
                            "'hwid run' fits the whole model to the staircases and sines instead")
    res = two.linear
    if json_out is not None:
        results.write_json(json_out, res.to_dict())
    for i, w in enumerate(res.frequencies):
        typer.echo(f"w = {w:g} rad/s: |G| = {res.gain[i]:.5g} [{res.gain_ci[i][0]:.5g}, {res.gain_ci[i][1]:.5g}]"
                   f"  phi = {res.phase[i]:.5g} [{res.phase_ci[i][0]:.5g}, {res.phase_ci[i][1]:.5g}] rad")
    said.warnings(res.warnings)
    why = "" if cfg.plant.kind == "recorded" else g_undetermined(res)
    if why:
        typer.echo(f"{why}: the two stages cannot stand for the plant; 'hwid run' fits the whole model instead")
    typer.echo(f"wrote {two.paths['linear']}")


@app.command("identify-nonlinear")
def identify_nonlinear(config: Path = typer.Argument(..., help="Config YAML."),
                       data: Optional[Path] = typer.Option(None, "--data", help="simulation.h5 holding the "
                                                           "staircases (default: run them on the config's plant)."),
                       out: Path = typer.Option(..., "--out", help="Output directory (nonlinear.h5 goes here)."),
                       json_out: Optional[Path] = typer.Option(None, "--json", help="Also write the result as JSON.")):
    """Stage 1 (Section 4): staircases -> h, the backlash borders and their type; OUT/nonlinear.h5.
    For a recorded plant: stage 1 from its levels in whatever order they were recorded; OUT/history.h5.
    The same step 'hwid run' takes (hwid.identify.path.stage1)."""
    from hwid.config import load as load_config
    from hwid.identify.path import input_moves, stage1
    from hwid.identify.result import format_history, format_summary
    cfg = load_config(config)
    out = _out_dir(out)
    said = _Said()
    if cfg.plant.kind == "recorded":
        from hwid.recorded import load_records
        records = load_records(cfg)        # a file that does not read is its own error, not stage 1's
        try:
            one = stage1(cfg, records=records, out_dir=out, echo=said)
        except HwidError as err:     # where the path fits the whole model instead, say so
            input_moves(cfg, records)   # ... unless nothing can be identified from these records
            line = str(err) if "hwid run" in str(err) else f"{err}; 'hwid run' fits the whole model to these records"
            raise HwidError(line) from None
        summary, path = format_history(one.result), one.paths["history"]
    else:
        one = stage1(cfg, data=data, out_dir=out, echo=said)
        summary, path = format_summary(one.result), one.paths["nonlinear"]
    if json_out is not None:
        from hwid.results import write_json
        write_json(json_out, one.result.to_dict())
    typer.echo(summary)
    said.warnings(one.result.warnings)
    typer.echo(f"wrote {path}")


def _one_line(msg: str) -> str:
    """Messages from rigs and libraries may span lines; the CLI prints one."""
    return " ".join(msg.split())


def _click_errors() -> tuple[type, ...]:
    """Click's usage-error base class: typer >= 0.16 vendors click as ``typer._click``."""
    types = []
    for mod in ("click.exceptions", "typer._click.exceptions"):
        try:
            types.append(__import__(mod, fromlist=["ClickException"]).ClickException)
        except (ImportError, AttributeError):
            pass
    return tuple(types)


@app.command("run")
def run_all(config: Path = typer.Argument(..., help="Config YAML."),
            out: Path = typer.Option(..., "--out", help="Output directory."),
            no_report: bool = typer.Option(False, "--no-report", help="Skip the HTML report.")):
    """The whole job: staircases, stage 1, stage 2 behind the estimated pre-compensator, the report."""
    import time
    from hwid.config import load as load_config
    from hwid.pipeline import run
    t0 = time.perf_counter()
    cfg = load_config(config)
    run(cfg, _out_dir(out), report=not no_report, echo=typer.echo)
    typer.echo(f"done in {time.perf_counter() - t0:.1f} s: {out}")


@app.command()
def batch(config: Path = typer.Argument(..., help="Config YAML (a simulated plant)."),
          runs: int = typer.Option(..., "--runs", help="Monte Carlo runs per sweep point."),
          out: Path = typer.Option(..., "--out", help="Output directory (batch.h5, batch.jsonl)."),
          jobs: int = typer.Option(1, "--jobs", "-j", help="Local worker processes."),
          sweep: list[str] = typer.Option([], "--sweep", help="KEY=V1,V2,... (repeatable; crossed)."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address tcp://host:port.")):
    """Monte Carlo over noise realisations, optionally crossed with config sweeps; resumable."""
    from hwid.config import load as load_config
    from hwid.batch import parse_sweep, run_batch
    from hwid.results import read_batch_summary
    cfg = load_config(config)
    if jobs < 1:
        raise HwidError("--jobs must be at least 1")
    path = run_batch(cfg, runs, _out_dir(out), [parse_sweep(s) for s in sweep], jobs=jobs, scheduler=scheduler)
    summ = read_batch_summary(path)
    for p in summ["points"]:
        typer.echo(f"{p['overrides'] or 'base config'}: {p['n_runs']} runs, {p['n_errors']} failed")
        for name, s in p["stats"].items():
            if name.startswith("h_c"):
                continue
            cov = f" coverage {s['coverage']:.3f}" if "coverage" in s else ""
            if s.get("without_interval"):       # neither covered nor missed (hwid.batch.summarise)
                cov += f" ({int(s['without_interval'])} run(s) without an interval, not counted)"
            eff = f" efficiency {s['efficiency']:.2f}" if "efficiency" in s else ""
            typer.echo(f"  {name:>14}: bias {s['bias']:+.2e} std {s['std']:.2e} rmse {s['rmse']:.2e}{cov}{eff}")
    typer.echo(f"wrote {path}")


@app.command()
def report(directory: Path = typer.Argument(..., help="Run directory (simulation.h5, nonlinear.h5, linear.h5, batch.h5).")):
    """Write DIR/report/: the figures (PNG and SVG) and one self-contained report.html."""
    from hwid.report import write_report
    typer.echo(f"wrote {write_report(directory)}")


@app.command()
def diagnose(config: Path = typer.Argument(..., help="Config YAML: its plant is the real side."),
             model: Optional[Path] = typer.Option(None, "--model", help="Sim side: a plant YAML (kind "
                                                  "hammerstein_wiener) or an 'hwid run' directory; "
                                                  "default: identify it from the plant first."),
             out: Path = typer.Option(..., "--out", help="Output directory (diagnosis.h5, rig_journal/)."),
             json_out: Optional[Path] = typer.Option(None, "--json", help="JSON summary (default OUT/diagnosis.json).")):
    """Where and why the plant and the model part: names the unmodelled effect of the catalogue."""
    from hwid.config import load as load_config
    from hwid.diagnose import diagnose as run
    cfg = load_config(config)
    run(cfg, _out_dir(out), model=model, json_path=json_out, echo=typer.echo)


@app.command()
def compare(model: Path = typer.Argument(..., help="The model: an 'hwid run' directory or a plant YAML "
                                         "(kind hammerstein_wiener)."),
            config: Path = typer.Argument(..., help="Config YAML whose experiments (recorded, simulated or a "
                                          "live rig) the model is compared with."),
            out: Path = typer.Option(..., "--out", help="Output directory (compare.h5, compare.json)."),
            json_out: Optional[Path] = typer.Option(None, "--json", help="JSON summary (default OUT/compare.json).")):
    """The model's free run against every experiment: fit %, RMS error, residual tests."""
    from hwid.config import load as load_config
    from hwid.compare import compare as run
    cfg = load_config(config)
    run(model, cfg, _out_dir(out), json_path=json_out, echo=typer.echo)


def main(argv: Optional[list[str]] = None) -> None:
    """Entry point: run the app, map user errors to one line and exit code 2."""
    try:
        app(args=argv, standalone_mode=False)
    except HwidError as err:
        sys.stderr.write(f"hwid: error: {_one_line(str(err))}\n")
        sys.exit(2)
    except typer.Exit as e:
        sys.exit(e.exit_code)
    except typer.Abort:
        sys.stderr.write("hwid: aborted\n")
        sys.exit(130)
    except KeyboardInterrupt:
        sys.stderr.write("hwid: interrupted (results written so far are kept)\n")
        sys.exit(130)
    except Exception as err:  # click usage errors carry their own exit code
        if isinstance(err, _click_errors()):
            where = getattr(getattr(err, "ctx", None), "command_path", None) or "hwid"
            sys.stderr.write(f"hwid: error: {_one_line(err.format_message())} (see '{where} --help')\n")
            sys.exit(2 if err.exit_code in (1, 2) else err.exit_code)
        raise
    sys.exit(0)
