"""The package's shape (issue 45's size and structure checks): no import cycle in ``hwid/`` (imports
at module level, inside functions and under ``TYPE_CHECKING`` alike), no file over 700 lines, no
function over 100 lines, no module importing another module's ``_private`` names."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "hwid"
MAX_FILE_LINES = 700
MAX_FUNCTION_LINES = 100


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict) -> list[tuple[str, list[str]]]:
    """``(module imported, names imported from it)`` for every import in the file, wherever it is."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [(a.name, []) for a in node.names if a.name in modules]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                head = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(head + ([base] if base else []))
            for a in node.names:
                if f"{base}.{a.name}" in modules:       # ``from package import module``
                    found.append((f"{base}.{a.name}", []))
                elif base in modules:
                    found.append((base, [a.name]))
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: {target for target, _ in _imports(m, p, modules) if target != m} for m, p in modules.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_known_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    assert _cycles(_graph()) == []


def test_no_file_over_the_limit():
    long = {str(p.relative_to(ROOT.parent)): n for p in ROOT.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_FILE_LINES}
    assert long == {}


def _functions(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node.name, node.end_lineno - node.lineno + 1


def test_no_function_over_the_limit():
    long = {f"{p.relative_to(ROOT.parent)}:{name}": n for p in ROOT.rglob("*.py")
            for name, n in _functions(p) if n > MAX_FUNCTION_LINES}
    assert long == {}


def test_no_private_name_imported_across_modules():
    modules = _modules()
    private = sorted(f"{m} imports {target}.{n}" for m, p in modules.items()
                     for target, names in _imports(m, p, modules) for n in names
                     if n.startswith("_") and not n.startswith("__") and target != m)
    assert private == []


def test_checks_are_not_vacuous():
    """The checks look at the whole package: its modules, their imports and their functions."""
    graph = _graph()
    assert len(graph) > 50 and sum(map(len, graph.values())) > 200
    assert sum(1 for p in ROOT.rglob("*.py") for _ in _functions(p)) > 500
