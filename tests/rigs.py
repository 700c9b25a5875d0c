"""Test rig drivers for ``plant.kind: external`` and small configs for fast robustness tests.

Each driver has the interface hwid expects of a real rig, ``function(u, dt) -> y``, and records its
calls so tests can check that hwid drives the rig exactly once per experiment:

* in the test process in :data:`CALLS` (a list of input lengths);
* across processes by appending one line per call to the file named by ``$HWID_TEST_RIG_LOG``.

The tests import this module as ``rigs`` (pytest puts ``tests/`` on ``sys.path``); subprocesses get
``tests/`` through ``PYTHONPATH``.
"""
from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

import numpy as np
import yaml

import plants

TESTS = Path(__file__).resolve().parent

CALLS: list[int] = []                 # input length of every call that reached a rig
FAIL_AFTER: int | None = None         # flaky(): calls that succeed before it starts failing
RELEASE = threading.Event()           # hanging(): set it to let a hung call finish


def reset(fail_after: int | None = None) -> None:
    global FAIL_AFTER
    CALLS.clear()
    FAIL_AFTER = fail_after
    RELEASE.clear()


def _log(u) -> None:
    CALLS.append(len(u))
    log = os.environ.get("HWID_TEST_RIG_LOG")
    if log:
        with open(log, "a") as fh:
            fh.write(f"{len(u)}\n")


def _respond(u: np.ndarray, dt: float) -> np.ndarray:
    """A well-behaved rig: a gear with play 0.2, a first-order lag (time constant 0.5 s), tanh."""
    v = np.empty_like(u)
    state = 0.0
    for i, ui in enumerate(u):            # backlash, eq. (1), unit slopes
        state = min(max(state, ui - 0.2), ui + 0.2)
        v[i] = state
    a = np.exp(-dt / 0.5)
    w = np.empty_like(v)
    acc = v[0]
    for i, vi in enumerate(v):
        acc = a * acc + (1 - a) * vi
        w[i] = acc
    return np.tanh(w)


# ---------------------------------------------------------------- drivers

def good(u, dt):
    _log(u)
    return _respond(np.asarray(u, float), dt)


def flaky(u, dt):
    """Good for the first ``FAIL_AFTER`` calls (or ``$HWID_TEST_RIG_FAIL_AFTER``), then raises."""
    limit = FAIL_AFTER if FAIL_AFTER is not None else int(os.environ.get("HWID_TEST_RIG_FAIL_AFTER", "-1"))
    if 0 <= limit <= len(CALLS):
        raise ConnectionError("rig connection lost")
    _log(u)
    return _respond(np.asarray(u, float), dt)


def raising(u, dt):
    _log(u)
    raise RuntimeError("motor driver fault\nencoder 2 not responding")   # two lines on purpose


def wrong_length(u, dt):
    _log(u)
    return _respond(np.asarray(u, float), dt)[:-3]


def with_nan(u, dt):
    _log(u)
    y = _respond(np.asarray(u, float), dt)
    y[7] = np.nan
    return y


def returns_none(u, dt):
    _log(u)
    return None


def exits(u, dt):
    _log(u)
    sys.exit(0)       # a rig script that quits must not end hwid with exit code 0


def hanging(u, dt):
    _log(u)
    RELEASE.wait(20.0)      # bounded, so a hung thread never outlives the test session by much
    return _respond(np.asarray(u, float), dt)


def wrong_signature(u):
    return u


NOT_CALLABLE = 3


# ---------------------------------------------------------------- small configs

SMALL = {
    "name": "small",
    "seed": 3,
    "sampling": {"dt": 0.05},
    "plant": {
        "kind": "hammerstein_wiener",
        "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0,
                               "d_plus": 0.5, "d_minus": -0.5},
        "linear": {"num": [1.0], "den": [1.0, 2.0]},
        "output_nonlinearity": {"polynomial": [0, 1.0, 0, -0.1]},
        "noise": {"std": 0.01},
    },
    "protocols": {
        "staircase": {"levels_up": [-1.0, -0.5, 0.0, 0.5, 1.0],
                      "levels_down": [1.0, 0.5, 0.0, -0.5, -1.0], "hold": 5.0},
        "sine": {"amplitude": 1.0, "frequencies": [0.5, 1.0], "periods": 2, "lead_in_periods": 1},
    },
}

N_EXPERIMENTS = 4    # staircase_up, staircase_down, sine_0, sine_1


def small(**changes) -> dict:
    """A deep copy of :data:`SMALL` with dotted keys replaced (``{"plant.noise.std": 0}``);
    the value :data:`DELETE` removes the key (:func:`plants.changed`)."""
    return plants.changed(SMALL, **changes)


DELETE = plants.DELETE


def external(callable_: str, timeout: float | None = None) -> dict:
    """The small config's protocols on an external plant."""
    d = small()
    d["name"] = "rig"
    d["plant"] = {"kind": "external", "callable": callable_}
    if timeout is not None:
        d["plant"]["timeout"] = timeout
    return d


def write(path: Path, data: dict | str) -> Path:
    path = Path(path)
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False))
    return path
