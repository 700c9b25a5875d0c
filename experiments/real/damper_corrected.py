"""The corrected simulator on the real damper (issue 48, item 4): ``hwid diagnose`` on the banded
rotary friction damper's 1 Hz, 30 lb test (``configs/recorded_brfd_whole.yaml``, 128 Hz), its
``corrected.yaml`` run free on that test and on the two tests it never saw (0.5 Hz 30 lb, 1 Hz
0 lb; ``configs/recorded_brfd_{0.5hz_30lb,1hz_0lb}_whole.yaml``, the same 128 Hz grid), beside the
models without the effect:

* ``whole fit``: ``hwid run``'s model of the 1 Hz, 30 lb test, which a user holds before any
  diagnosis (the diagnosis identifies the same model on the same fit blocks, ``OUT/diag/whole.h5``);
* ``corrected``: ``OUT/diag/corrected.yaml``, that model's F, G and h as the friction's joint fit
  left them, with the verdict's effect added.

Each is run as ``hwid compare`` runs a model (:func:`hwid.compare.compare_records`: from the
initial state that fits best); the table gives fit % and RMS over the noise floor read from each
record, and one figure per test shows force against displacement, measured and modelled.

Usage: ``python experiments/real/damper_corrected.py [--out runs/damper_corrected] [--write]``.
The fit and the diagnosis are run once into OUT and reused. ``--write`` writes the figures to
``docs/tutorials/img/damper_corrected_<test>.png`` and the table to the fragment
``docs/validation/generated/damper_corrected.md`` (:mod:`docs/fragment.py`) that
``docs/tutorials/damper.md`` includes. Needs ../shared/data/real (``HWID_REAL_DATA`` elsewhere).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from hwid import config  # noqa: E402
from hwid.compare import compare_records, fit_percent  # noqa: E402
from hwid.diagnose.sim_side import load_model  # noqa: E402
from hwid.recorded import load_records  # noqa: E402

#: the real data: ``HWID_REAL_DATA`` where set (a checkout elsewhere), else ../shared/data/real
REAL = Path(os.environ.get("HWID_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
FITTED = "recorded_brfd_whole.yaml"
#: test label -> config (the first is the test the model is fitted and diagnosed on)
TESTS = {"1 Hz, 30 lb": FITTED,
         "0.5 Hz, 30 lb": "recorded_brfd_0.5hz_30lb_whole.yaml",
         "1 Hz, 0 lb": "recorded_brfd_1hz_0lb_whole.yaml"}
IMG = ROOT / "docs" / "tutorials" / "img"
SCRIPT = "experiments/real/damper_corrected.py"


@dataclass(frozen=True)
class Score:
    """One model run free on one test: fit %, RMS (kip) and the record's noise floor (kip)."""

    test: str
    model: str
    fit_percent: float
    rms: float
    floor: float | None
    y_hat: np.ndarray

    @property
    def ratio(self) -> float | None:
        return None if not self.floor else self.rms / self.floor

    def to_dict(self) -> dict:
        return {"test": self.test, "model": self.model, "fit_percent": self.fit_percent, "rms": self.rms,
                "floor": self.floor, "rms_over_floor": self.ratio}


def rescaled_fit(y: np.ndarray, y_hat: np.ndarray) -> tuple[float, float]:
    """The fit % of ``a y_hat + b`` with the gain ``a`` and offset ``b`` fitted to ``y`` by least squares, and
    ``a``: how much of a miss is the force's level alone (a diagnostic, not a model's prediction)."""
    phi = np.column_stack([y_hat, np.ones_like(y_hat)])
    (a, b), *_ = np.linalg.lstsq(phi, y, rcond=None)
    return fit_percent(y, a * y_hat + b), float(a)


def load_config(name: str, tmp: Path) -> config.Config:
    """``configs/<name>`` with its data file looked up in :data:`REAL`."""
    d = yaml.safe_load((ROOT / "configs" / name).read_text())
    for exp in d["plant"]["experiments"]:
        exp["file"] = str(REAL / "brfd" / Path(exp["file"]).name)
    path = tmp / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return config.load(path)


def hwid(*args: str) -> None:
    """The hwid CLI of this checkout, as a user runs it."""
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    subprocess.run([sys.executable, "-m", "hwid", *args], check=True, env=env, stdout=subprocess.DEVNULL)


def prepare(out: Path, run: bool = True) -> dict:
    """``hwid diagnose`` (from the log) and, with ``run``, ``hwid run`` on the fitted test, each once
    into ``out``; returns the models to compare (label -> path) and the diagnosis's JSON. The
    diagnosis identifies its model by ``hwid run``'s route on the same fit blocks, so the two are
    one model (checked where both are there); without ``run`` the diagnosis's copy stands for it."""
    out.mkdir(parents=True, exist_ok=True)
    cfg_path = out / "configs"
    load_config(FITTED, cfg_path)
    if not (out / "diag" / "diagnosis.json").is_file():
        hwid("diagnose", str(cfg_path / FITTED), "--out", str(out / "diag"))
    whole = out / "diag"
    if run:
        if not (out / "run" / "identification.json").is_file():
            hwid("run", str(cfg_path / FITTED), "--out", str(out / "run"))
        quiet = lambda *a, **k: None  # noqa: E731
        if load_model(str(out / "run"), echo=quiet)[0] != load_model(str(whole), echo=quiet)[0]:
            sys.exit(f"{out / 'run'} and the model {out / 'diag'} diagnosed differ")
        whole = out / "run"
    return {"models": {"whole fit": whole, "corrected": out / "diag" / "corrected.yaml"},
            "diagnosis": json.loads((out / "diag" / "diagnosis.json").read_text())}


def score_all(models: dict, tmp: Path) -> tuple[list[Score], dict]:
    """Every model on every test; returns the scores and each test's record."""
    quiet = lambda *a, **k: None  # noqa: E731
    loaded = {label: load_model(str(path), echo=quiet)[0] for label, path in models.items()}
    scores, records = [], {}
    for test, name in TESTS.items():
        (rec,) = load_records(load_config(name, tmp))
        records[test] = rec
        for label, model in loaded.items():
            result, sims = compare_records(model, [rec])
            scores.append(Score(test, label, result.fit_percent, result.rms, result.noise_floor, sims[rec.name]))
    return scores, records


def grid_check(corrected: Path, tmp: Path) -> dict:
    """The corrected model on the fitted test at the recording's own 1024 Hz (``configs/brfd/1hz_30lb.yaml``):
    its fit % on the displacement as recorded, and on the displacement smoothed (Savitzky-Golay, cubic over
    41 samples, 40 ms). The effect's parameters are not per sample (Dahl's state is solved exactly over
    each sample's move, the viscous term is per second), but the displacement's noise at 1024 Hz reverses
    its direction many times near each turn, and every reversal moves the Backlash-Inverse across its
    gap and restarts the Dahl state."""
    from scipy.signal import savgol_filter

    from hwid.plant import Record
    (rec,) = load_records(load_config("brfd/1hz_30lb.yaml", tmp))
    model = load_model(str(corrected), echo=lambda *a, **k: None)[0]
    smooth = savgol_filter(rec.u, 41, 3)
    out = {"dt": rec.dt}
    for label, u in (("as recorded", rec.u), ("smoothed", smooth)):
        du = np.diff(u)
        result, _ = compare_records(model, [Record(rec.name, rec.dt, u, rec.y)])
        out[label] = {"fit_percent": result.fit_percent, "rms": result.rms, "floor": result.noise_floor,
                      "reversals": int(np.sum(np.diff(np.sign(du[du != 0])) != 0))}
    return out


def figure(test: str, rec, scores: list[Score], path: Path) -> None:
    """Force against displacement on ``test``: measured, and each model's free run, one panel each."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    mine = [s for s in scores if s.test == test]
    fig = Figure(figsize=(3.4 * len(mine), 3.4), layout="constrained")
    axes = fig.subplots(1, len(mine), sharex=True, sharey=True, squeeze=False)[0]
    for ax, s in zip(axes, mine):
        ax.plot(rec.u, rec.y, color="0.6", lw=1.0, label="measured")
        ax.plot(rec.u, s.y_hat, color="C3" if s.model == "corrected" else "C0", lw=1.0, label=s.model)
        ratio = f", {s.ratio:.2f}x floor" if s.ratio is not None else ""
        ax.set_title(f"{s.model}: fit {s.fit_percent:.1f} %{ratio}", fontsize=9)
        ax.set_xlabel("displacement (in)")
        ax.legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("friction force (kip)")
    fig.suptitle(f"{test} test" + (" (fitted and diagnosed)" if TESTS[test] == FITTED else " (held out)"), fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def image_name(test: str) -> str:
    return "damper_corrected_" + test.replace(" Hz, ", "hz_").replace(" lb", "lb").replace(".", "_") + ".png"


def table(scores: list[Score], diagnosis: dict) -> str:
    """The markdown fragment: the diagnosis's verdict line, then fit % and RMS / floor per test and model."""
    v = diagnosis["verdict"]
    labels = list(dict.fromkeys(s.model for s in scores))
    head = (f"Diagnosis of the 1 Hz, 30 lb test from the log: verdict **`{v['effect']}`** (block {v['block']}, "
            f"explained {v['explained_fraction']:.2f}); gap {diagnosis['gap_before']:.3f} -> "
            f"{diagnosis['gap_after']:.3f} kip on its validation blocks, noise floor {diagnosis['noise_floor']:.3f} kip.\n\n")
    rows = ["| test | " + " | ".join(f"{m}: fit % | {m}: RMS (kip) / floor" for m in labels) + " |",
            "|---|" + "---|---|" * len(labels)]
    for test in TESTS:
        cells = []
        for m in labels:
            s = next(x for x in scores if x.test == test and x.model == m)
            ratio = f"{s.ratio:.2f}x" if s.ratio is not None else "floor undetermined"
            cells += [f"{s.fit_percent:.1f}", f"{s.rms:.3f} / {ratio}"]
        rows.append(f"| {test}{' (fitted)' if TESTS[test] == FITTED else ' (held out)'} | " + " | ".join(cells) + " |")
    return head + "\n".join(rows) + "\n"


def grid_note(check: dict) -> str:
    raw, smooth = check["as recorded"], check["smoothed"]
    return (f"\nThe same corrected model on the fitted test at the recording's own 1024 Hz: fit "
            f"{raw['fit_percent']:.1f} % on the displacement as recorded ({raw['reversals']} reversals of its "
            f"direction), {smooth['fit_percent']:.1f} % on it smoothed over 40 ms ({smooth['reversals']} reversals); "
            f"RMS {raw['rms']:.3f} kip against the noise floor {raw['floor']:.3f} kip read there.\n")


def level_note(scores: list[Score], records: dict) -> str:
    """Per held-out test, the force's level against the fitted test's, and the fit % each model
    would reach with one gain and offset fitted on that test (:func:`rescaled_fit`)."""
    fitted = next(t for t, n in TESTS.items() if n == FITTED)
    level = lambda y: float(np.percentile(np.abs(y - np.median(y)), 90))  # noqa: E731
    lines = []
    for test, rec in records.items():
        if test == fitted:
            continue
        parts = []
        for s in (x for x in scores if x.test == test):
            fit, gain = rescaled_fit(rec.y, s.y_hat)
            parts.append(f"{s.model} {fit:.1f} % (gain {gain:.2f})")
        lines.append(f"- {test}: the force's level (90th percentile of |y - median|) {level(rec.y):.2f} kip against "
                     f"{level(records[fitted].y):.2f} on the fitted test; with one gain and offset fitted on this "
                     f"test (a diagnostic, not a prediction): " + ", ".join(parts) + ".")
    return "\n" + "\n".join(lines) + "\n"


def main(argv: list[str]) -> None:
    if not (REAL / "brfd").is_dir():
        sys.exit(f"needs the real damper data ({REAL / 'brfd'})")
    out = Path(argv[argv.index("--out") + 1]) if "--out" in argv else ROOT / "runs" / "damper_corrected"
    prep = prepare(out)
    scores, records = score_all(prep["models"], out / "configs")
    check = grid_check(prep["models"]["corrected"], out / "configs")
    md = table(scores, prep["diagnosis"]) + level_note(scores, records) + grid_note(check)
    print(md)
    (out / "scores.json").write_text(json.dumps({"scores": [s.to_dict() for s in scores], "grid_check": check},
                                                indent=1))
    if "--write" in argv:
        for test, rec in records.items():
            figure(test, rec, scores, IMG / image_name(test))
        sys.path.insert(0, str(ROOT / "docs"))
        from fragment import write
        print(f"wrote {write('damper_corrected', md, SCRIPT)}")


if __name__ == "__main__":
    main(sys.argv[1:])
