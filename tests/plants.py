"""The simulated plants the tests share, as config dicts, written once.

``config_text(PLANT, **changes)`` gives YAML text with dotted keys replaced
(``{"plant.noise.std": 0}``; :data:`DELETE` removes a key); ``load(PLANT, **changes)`` the loaded
:class:`hwid.config.Config`. Tests import this module as ``plants`` (pytest puts ``tests/`` on
``sys.path``).
"""
from __future__ import annotations

import copy

import yaml

from hwid import config

DELETE = object()

#: The paper's backlash and h (Section 6) behind a fast G (time constant 0.2 s): short holds, cheap
#: stage-1 runs.
PAPER_FAST_G = {
    "name": "fast",
    "seed": 5,
    "sampling": {"dt": 0.01},
    "plant": {
        "kind": "hammerstein_wiener",
        "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.5, "d_minus": -0.5},
        "linear": {"num": [5.0], "den": [1.0, 5.0]},
        "output_nonlinearity": {"polynomial": [0, 0.5, 0, -3.36, 0, 6.4]},
        "noise": {"std": 0.01},
    },
    "protocols": {
        "staircase": {"levels_up": [-1.0, -0.7, -0.4, -0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2],
                      "levels_down": [1.0, 0.8, 0.6, 0.4, 0.25, 0.0, -0.3, -0.6, -1.0, -1.2, -1.4],
                      "hold": 5.0},
    },
}

#: An asymmetric backlash behind a first-order G with both protocols: the Monte Carlo batch's plant.
BATCH = {
    "name": "fast",
    "seed": 7,
    "sampling": {"dt": 0.05},
    "plant": {
        "kind": "hammerstein_wiener",
        "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.2, "d_plus": 0.4, "d_minus": -0.3},
        "linear": {"num": [2.0], "den": [1.0, 2.0]},
        "output_nonlinearity": {"polynomial": [0, 0.5, 0, -0.2, 0, 0.1]},
        "noise": {"std": 0.01},
    },
    "protocols": {
        "staircase": {"levels_up": [-1.0, -0.8, -0.6, -0.2, 0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2],
                      "levels_down": [0.9, 0.7, 0.5, 0.3, 0.1, -0.1, -0.3, -0.5, -0.7, -0.9, -1.1], "hold": 6.0},
        "sine": {"amplitude": 0.8, "frequencies": [0.5, 2.0], "periods": 4, "lead_in_periods": 2},
    },
}


def changed(plant: dict, /, **changes) -> dict:
    """A deep copy of ``plant`` with dotted keys replaced; the value :data:`DELETE` removes the key."""
    d = copy.deepcopy(plant)
    for key, val in changes.items():
        node = d
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        if val is DELETE:
            node.pop(parts[-1], None)
        else:
            node[parts[-1]] = val
    return d


def config_text(plant: dict, /, **changes) -> str:
    return yaml.safe_dump(changed(plant, **changes), sort_keys=False)


def load(plant: dict, /, **changes) -> config.Config:
    return config.loads(config_text(plant, **changes))
