"""The API's names that are also modules: ``hwid.identify``, ``hwid.compare`` and ``hwid.diagnose``.

Each is both a module of the package (the subpackage :mod:`hwid.identify`, the module
:mod:`hwid.compare`, the subpackage :mod:`hwid.diagnose`) and a function of the Python API
(:func:`hwid.api.identify`, :func:`hwid.api.compare`, :func:`hwid.api.diagnose`). Importing a
module binds its name in ``hwid`` to the module, whatever ``hwid`` held there, so the two cannot be
separate objects: the module is made callable, and a call is the API function's.
"""
from __future__ import annotations

import importlib
import sys
import types


def callable_as(module_name: str, api_name: str) -> None:
    """Make the module ``module_name`` (already in ``sys.modules``) callable as ``hwid.api.<api_name>``."""

    class _Module(types.ModuleType):
        def __call__(self, *args, **kwargs):
            # by name, at call time: hwid.api imports the modules made callable here
            api = importlib.import_module("hwid.api")
            return getattr(api, api_name)(*args, **kwargs)

    _Module.__call__.__doc__ = f"A call is :func:`hwid.api.{api_name}`."
    sys.modules[module_name].__class__ = _Module
