"""The progress bar (rich): silent unless stderr is a terminal or HWID_PROGRESS=1, counts what it is told."""
import subprocess
import sys

SCRIPT = ("from hwid.progress import Progress\n"
          "with Progress(40, 'simulate', 'samples') as bar:\n"
          "    for _ in range(4):\n"
          "        bar.update(10)\n"
          "print(bar.done)\n")


def _run(env_value):
    env = {"PATH": "/usr/bin:/bin", "COLUMNS": "120"}
    if env_value is not None:
        env["HWID_PROGRESS"] = env_value
    return subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=60)


def test_progress_is_silent_when_stderr_is_not_a_terminal():
    p = _run(None)
    assert p.returncode == 0 and p.stdout.strip() == "40" and p.stderr == ""


def test_progress_draws_done_of_total_when_asked():
    p = _run("1")
    assert p.returncode == 0 and p.stdout.strip() == "40"
    assert "simulate" in p.stderr and "40/40" in p.stderr and "samples" in p.stderr
