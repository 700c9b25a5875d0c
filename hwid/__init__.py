"""hwid: identification of Hammerstein-Wiener systems with Backlash / Backlash-Inverse input.

Implements Brouri et al., "Frequency identification of Hammerstein-Wiener systems with Backlash
input nonlinearity" (the paper in ``shared/paper``). Equation numbers in docstrings refer to it.

The Python API (:mod:`hwid.api`), imported on first use so ``import hwid`` stays light:
:class:`Data`, :func:`identify`, :class:`Model`, :func:`compare`, :func:`diagnose`.
"""

__version__ = "0.1.0"

__all__ = ["Data", "Model", "identify", "compare", "diagnose", "HwidError", "__version__"]

#: the API's classes, each imported from :mod:`hwid.api` when first used
_API = ("Data", "Model")
#: the API's functions that are also modules, made callable (:mod:`hwid.apinames`)
_MODULES = ("identify", "compare", "diagnose")


class HwidError(ValueError):
    """An error the user can fix (bad config, bad data, failing rig): the CLI prints one line, exit 2."""


def __getattr__(name: str):
    """The API's names on first use (PEP 562). Imported by name, at the first access after ``hwid``
    itself is complete: the package's modules import :class:`HwidError` from here, and the API
    imports them, so a static import of the API here would close that loop."""
    import importlib
    if name in _API:
        return getattr(importlib.import_module("hwid.api"), name)
    if name in _MODULES:
        return importlib.import_module(f"hwid.{name}")
    raise AttributeError(f"module 'hwid' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
