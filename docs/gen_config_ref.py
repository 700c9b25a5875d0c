"""The config reference, rendered from the schema in ``hwid/config.py``.

Every key reachable from :class:`hwid.config.Config` becomes one row: its dotted path, its type
with the schema's checks, its default, its allowed values and its ``Field(description=...)``.
``python docs/gen_config_ref.py`` writes ``docs/reference/config.md``; ``mkdocs build`` runs the
same through ``hooks:`` in ``mkdocs.yml`` (:func:`on_pre_build`), and
``tests/test_config_reference.py`` fails when a key has no description or the page is stale.
"""
from __future__ import annotations

import os
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Union

from annotated_types import Ge, Gt, Le, Lt, MaxLen, MinLen
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

PAGE = Path(__file__).resolve().parent / "reference" / "config.md"

HEADER = """# Config reference

Generated from the schema in `hwid/config.py` by `docs/gen_config_ref.py` (do not edit by hand:
`make docs` writes it again). Unknown keys are rejected with the nearest valid name, a key given
twice is an error, and every failure is one line `FILE: key.path: reason` with exit code 2;
`hwid check CONFIG` validates a file without running anything.

A key under a list is written `key[]` (one entry per list item); under a list whose items are one
of several kinds, `key[KIND]` (`plant.effects[rate_limit].rate` is the `rate` of an entry
`{effect: rate_limit, ...}`). `required` means the key must be
given when its parent is; the plant kinds' own rules (which parts each kind needs) are in
[Plant kinds](../guide/plants.md).

| key | type and checks | default | allowed values | meaning |
|---|---|---|---|---|
"""

FOOTER = """
Checks that need the whole config: the borders must not cross inside the staircase range
(`plant.input_nonlinearity`); a fixed `identification.nonlinear.degree` needs at least
`degree + 1` levels per staircase (eq. 11); each sine frequency must lie below the Nyquist
frequency pi/dt with at least 8 samples a period; no experiment may last more than 10^8 samples.
"""


@dataclass(frozen=True)
class Key:
    """One row of the reference."""

    path: str
    type: str
    default: str
    allowed: str
    description: str


def _models(ann) -> list[type[BaseModel]]:
    """The pydantic models an annotation holds (directly, in a list, or in an Optional)."""
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return [ann]
    return [m for a in typing.get_args(ann) for m in _models(a)]


def _is_list_of_models(ann) -> bool:
    origin = typing.get_origin(ann)
    if origin is list:
        return bool(_models(ann))
    return any(_is_list_of_models(a) for a in typing.get_args(ann) if a is not type(None))


def _checks(metadata) -> list[str]:
    out = []
    for m in metadata:
        if isinstance(m, FieldInfo):            # Field(...) inside Annotated: its own constraints
            out += _checks(m.metadata)
            continue
        for cls, attr, sym in ((Gt, "gt", ">"), (Ge, "ge", ">="), (Lt, "lt", "<"), (Le, "le", "<=")):
            if isinstance(m, cls):
                bound = getattr(m, attr)
                out.append(f"{sym} {'2^63' if bound == 2**63 else bound}")
        if isinstance(m, MinLen) and m.min_length > 1:
            out.append(f"length >= {m.min_length}")
        if isinstance(m, MaxLen):
            out.append(f"length <= {m.max_length}")
        pattern = getattr(m, "pattern", None)
        if isinstance(pattern, str):
            out.append(f"matches `{pattern}`")
    return out


def _type(ann) -> str:
    """A reader's name for a type, with the checks its ``Annotated`` metadata carries."""
    origin = typing.get_origin(ann)
    args = typing.get_args(ann)
    if origin is typing.Annotated:
        base, checks = _type(args[0]), _checks(args[1:])
        return f"{base} ({', '.join(checks)})" if checks else base
    if origin is Literal:
        return "string"
    if origin is Union and all(isinstance(a, type) and issubclass(a, BaseModel) for a in args):
        return "mapping, one of the kinds below"
    if origin is Union:
        parts = [_type(a) for a in args if a is not type(None)]
        text = " or ".join(parts)
        return f"{text} or null" if type(None) in args else text
    if origin is list:
        return f"list of {_type(args[0])}"
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return "mapping"

    return {float: "number", int: "integer", str: "string", bool: "boolean"}.get(ann, str(ann))


def _allowed(ann) -> str:
    origin = typing.get_origin(ann)
    if origin is Literal:
        return " \\| ".join(f"`{v}`" for v in typing.get_args(ann))
    return next((a for a in map(_allowed, typing.get_args(ann)) if a), "")


def _default(field) -> str:
    if field.is_required():
        return "required"
    if field.default_factory is not None:
        value = field.default_factory()
        return "neither protocol" if isinstance(value, BaseModel) else f"`{value!r}`"
    value = field.default
    if value is None:
        return "null"
    if isinstance(value, BaseModel):
        return "(its keys' defaults)"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    return f"`{value}`" if value is not PydanticUndefined else "required"


def keys(model: type[BaseModel] | None = None, prefix: str = "") -> list[Key]:
    """Every key of the schema below ``model`` (default: the whole config), depth first."""
    from hwid.config import Config
    model = Config if model is None else model
    out: list[Key] = []
    for name, field in model.model_fields.items():
        if field.exclude:                       # set by load(), not a key a user writes
            continue
        path = f"{prefix}{name}"
        ann = field.annotation
        checks = _checks(field.metadata)
        kind = _type(ann) + (f" ({', '.join(checks)})" if checks else "")
        out.append(Key(path, kind, _default(field), _allowed(ann), (field.description or "").strip()))
        subs = _models(ann)
        for sub in subs:
            tag = _tag(sub) if len(subs) > 1 else ""
            out += keys(sub, f"{path}[{tag}]." if _is_list_of_models(ann) else f"{path}.")
    return out


def _tag(model: type[BaseModel]) -> str:
    """The value that picks ``model`` out of a union of mappings (its first key's one allowed
    value: ``effect: rate_limit``), written in the path as ``effects[rate_limit]``."""
    first = next(iter(model.model_fields.values()))
    values = typing.get_args(first.annotation) if typing.get_origin(first.annotation) is Literal else ()
    return str(values[0]) if len(values) == 1 else model.__name__


def render() -> str:
    """The reference page's markdown."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|")
    rows = [f"| `{k.path}` | {cell(k.type)} | {k.default} | {k.allowed} | "
            f"{cell(k.description) or '**no description**'} |" for k in keys()]
    return HEADER + "\n".join(rows) + "\n" + FOOTER


def write(path: Path = PAGE) -> bool:
    """Write the page if its text changed (atomically); return whether it did."""
    text = render()
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return True


def on_pre_build(config: Any, **kwargs) -> None:
    """mkdocs hook: the reference written afresh before every build."""
    write()


if __name__ == "__main__":
    print(f"{PAGE}: {'written' if write() else 'up to date'}")
