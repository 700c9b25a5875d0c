"""hwid uses only the public, documented APIs of numba and numpy: no module of the package imports
or reaches a private (``_``-prefixed) name of either, and numba only through its documented public
modules, so a user's own numba or numpy of any version the lower bounds allow fits beside hwid."""
import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "hwid"
LIBRARIES = ("numba", "numpy")
NUMBA_PUBLIC = {"numba", "numba.typed", "numba.types", "numba.extending", "numba.experimental"}


def private(name: str) -> bool:
    """A dotted name with a ``_``-prefixed part (dunders such as ``__version__`` are public)."""
    return any(p.startswith("_") and not (p.startswith("__") and p.endswith("__")) for p in name.split("."))


def findings(source: str) -> list[str]:
    """The uses of numba's or numpy's private names, or of numba's internal modules, in ``source``."""
    found, aliases = [], {}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in LIBRARIES:
                    aliases[(a.asname or a.name).split(".")[0]] = a.name.split(".")[0]
                    if private(a.name) or (a.name.startswith("numba.") and a.name not in NUMBA_PUBLIC):
                        found.append(f"line {node.lineno}: import {a.name}")
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in LIBRARIES:
            names = [a.name for a in node.names]
            if (private(node.module) or any(private(n) for n in names)
                    or (node.module.startswith("numba") and node.module not in NUMBA_PUBLIC)):
                found.append(f"line {node.lineno}: from {node.module} import {', '.join(names)}")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            chain, base = [node.attr], node.value
            while isinstance(base, ast.Attribute):
                chain.append(base.attr)
                base = base.value
            if isinstance(base, ast.Name) and base.id in aliases and private(".".join(chain)):
                found.append(f"line {node.lineno}: {base.id}.{'.'.join(reversed(chain))}")
    return found


@pytest.mark.parametrize("source, caught", [
    ("from numba.np.random._constants import wi_double", True),
    ("from numba.np.random.generator_core import next_double", True),
    ("import numpy as np\nx = np.random._pcg64.PCG64", True),
    ("from numpy.core import _multiarray_umath", True),
    ("import numba as nb\nf = nb._helperlib", True),
    ("from numba import njit\nimport numpy as np\nv = np.__version__", False),
])
def test_the_check_catches_private_names(source, caught):
    assert bool(findings(source)) == caught


def test_no_module_uses_private_numba_or_numpy():
    bad = {str(p.relative_to(PACKAGE.parent)): f for p in sorted(PACKAGE.rglob("*.py"))
           if (f := findings(p.read_text()))}
    assert not bad, bad
