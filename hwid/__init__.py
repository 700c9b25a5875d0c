"""hwid: identification of Hammerstein-Wiener systems with Backlash / Backlash-Inverse input.

Implements Brouri et al., "Frequency identification of Hammerstein-Wiener systems with Backlash
input nonlinearity" (the paper in ``shared/paper``). Equation numbers in docstrings refer to it.
"""

__version__ = "0.1.0"


class HwidError(ValueError):
    """An error the user can fix (bad config, bad data, failing rig): the CLI prints one line, exit 2."""
