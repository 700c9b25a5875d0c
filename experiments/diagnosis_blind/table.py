"""The blind checks' table on the docs page, from the runner's ``RESULTS-<way>.json`` files.

    python experiments/diagnosis_blind/table.py SEED=DIR [SEED=DIR ...] [--write] [--commit REV]

``DIR`` is a generated seed's folder after ``run.py`` (every way found there is a row). ``--write``
replaces ``docs/validation/generated/blind.md`` (:mod:`docs.fragment`); the commit stamped is the
one the diagnoses ran (``hwid_commit`` in the results, or ``--commit``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "docs"))
from fragment import write  # noqa: E402

WAYS = {"model": "live, `--model`", "identify": "live, identified", "recorded-model": "CSV, `--model`",
        "recorded-identify": "CSV, identified"}


def rows(pairs: list[tuple[str, Path]]) -> tuple[list[str], set[str]]:
    lines, commits = [], set()
    for seed, folder in pairs:
        for way, label in WAYS.items():
            f = folder / f"RESULTS-{way}.json"
            if not f.is_file():
                continue
            r = json.loads(f.read_text())
            commits.add(r.get("hwid_commit", "unknown"))
            g = r["gap_after_over_noise_correct"]
            credit = (f"; {r['credit']:g} with half credit" if r.get("halves") else "")
            lines.append(f"| {seed} | {label} | **{r['correct']}/{r['n']} ({100 * r['accuracy']:.0f} %)**{credit} | "
                         f"{r['false_alarms_on_none']}/{r['n_none']} | {r['outside_unexplained']}/{r['n_outside']} | "
                         f"{g['within_1.5']}/{g['n']} | median {r['seconds']['median']:.0f} s, "
                         f"max {r['seconds']['max']:.0f} s |")
    return lines, commits


def main(argv: list[str]) -> int:
    write_it = "--write" in argv
    commit = argv[argv.index("--commit") + 1] if "--commit" in argv else None
    pairs = [(a.split("=", 1)[0], Path(a.split("=", 1)[1])) for a in argv if "=" in a]
    if not pairs:
        print(__doc__)
        return 2
    lines, commits = rows(pairs)
    md = "\n".join(["| seed | way | correct | false alarms (plain rigs) | outside effects → `unexplained` | "
                    "correct named verdicts within 1.5× the floor | time per diagnosis |",
                    "|---|---|---|---|---|---|---|"] + lines)
    print(md)
    if write_it:
        stamp = commit or ", ".join(sorted(commits))
        print(f"wrote {write('blind', md, 'experiments/diagnosis_blind/table.py', stamp)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
