"""``hwid diagnose`` on the real logs in ../shared/data/real (issue 18): the banded rotary friction
damper with the model hwid identifies from it and with the plain backlash model a user would try
first, and the STS3215 servo log with the model hwid identifies from it, as recorded and with the
puller servos' pushes excluded (``exclude``). Prints what each says.

Usage: ``python experiments/real/diagnose_logs.py [OUT]`` (default ``runs/real_diagnose``); the
configs are ``configs/recorded_brfd_whole.yaml`` (the damper's 1 Hz test at 128 Hz) and
``configs/recorded_sts3215.yaml``. Needs ``../shared/data/real``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from hwid import HwidError  # noqa: E402
from hwid.config import load  # noqa: E402
from hwid.diagnose import diagnose  # noqa: E402
from hwid.recorded import load_records  # noqa: E402


def plain_backlash(cfg, path: Path) -> Path:
    """The model a user would try first on a damper: a backlash of a tenth of the stroke, a fast
    first-order G, h the gain from the stroke to the force range."""
    recs = load_records(cfg)
    u = np.concatenate([r.u for r in recs])
    y = np.concatenate([r.y for r in recs])
    play = 0.1 * float(np.ptp(u))
    gain = float(np.ptp(y)) / max(float(np.ptp(u)) - play, 1e-12)
    model = {"plant": {"kind": "hammerstein_wiener",
                       "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0,
                                              "d_plus": 0.5 * play, "d_minus": -0.5 * play},
                       "linear": {"num": [1.0], "den": [0.01, 1.0]},
                       "output_nonlinearity": {"polynomial": [0.0, gain]}}}
    path.write_text(yaml.safe_dump(model, sort_keys=False))
    return path


def say(name: str, s: dict) -> None:
    v = s["verdict"]
    alike = f" (indistinguishable from {', '.join(v['indistinguishable_from'])})" if v["indistinguishable_from"] else ""
    print(f"{name}: verdict {v['effect']}{alike}, block {v['block']}, explained {v['explained_fraction']:.2f}; "
          f"gap {s['gap_before']:.4g} -> {s['gap_after']:.4g}, noise floor {s['noise_floor']:.4g} "
          f"({s['data']['noise_source']}); split {s['data']['split']}")
    print("   top candidates: " + ", ".join(f"{c['effect']} {c['explained_fraction']:.2f}" for c in s["candidates"][:4]))
    for item in s["residual_structure"]:
        print(f"   remainder: {item['kind']} (p {item['p_value']:.2g}): {item['evidence']}")
    if s.get("next_experiment"):
        print(f"   next experiment: {s['next_experiment']['why']}")


def main(out: Path) -> None:
    if not (ROOT.parent / "shared" / "data" / "real").exists():
        sys.exit("needs ../shared/data/real (the measured logs and their SOURCES.md)")
    out.mkdir(parents=True, exist_ok=True)
    quiet = lambda *a: None  # noqa: E731
    damper = load(ROOT / "configs" / "recorded_brfd_whole.yaml")
    say("damper, model identified from it", diagnose(damper, out / "brfd_identified", echo=quiet))
    say("damper, plain backlash model", diagnose(damper, out / "brfd_backlash",
                                                 model=plain_backlash(damper, out / "brfd_backlash.yaml"), echo=quiet))
    sts_path = ROOT / "configs" / "recorded_sts3215.yaml"
    sts = load(sts_path)
    say("STS3215, model identified from it", diagnose(sts, out / "sts_identified", echo=quiet))
    masked = without_pushes(sts_path, out / "sts_without_pushes.yaml")
    records = load_records(load(masked))
    print(f"STS3215 with the pushes excluded: {len(records)} record(s), {sum(r.u.size for r in records)} samples")
    try:
        say("STS3215 with the pushes excluded, model identified from it",
            diagnose(load(masked), out / "sts_without_pushes", echo=quiet))
    except HwidError as err:
        print(f"STS3215 with the pushes excluded: {err}")


def without_pushes(config: Path, path: Path, after_s: float = 1.0) -> Path:
    """The STS3215 config with every stretch in which a puller servo is not relaxed excluded
    (``exclude``), and ``after_s`` after it while the lever springs back."""
    import pandas as pd
    from sts3215 import relaxed, runs
    data = yaml.safe_load(config.read_text())
    exp = data["plant"]["experiments"][0]
    csv = (config.parent / exp["file"]).resolve()
    df = pd.read_csv(csv)
    present = df[[exp["input"]["column"], exp["output"]["column"]]].notna().all(axis=1).to_numpy()
    df = df[np.cumsum(present) > 0]          # the record starts at its first row with both signals
    t = pd.to_datetime(df[exp["time"]["column"]], format="ISO8601")
    seconds = (t - t.iloc[0]).dt.total_seconds().to_numpy()
    pushed = ~relaxed(df)
    exp["exclude"] = [[float(max(seconds[a] - 0.05, 0.0)), float(seconds[b - 1] + after_s)] for a, b in runs(pushed)]
    exp["file"] = str(csv)
    data["name"] = data["name"] + "-without-pushes"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    print(f"STS3215: {len(exp['exclude'])} pushes excluded ({int(pushed.sum())} of {pushed.size} rows, "
          f"and {after_s:g} s after each)")
    return path


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "runs" / "real_diagnose")
