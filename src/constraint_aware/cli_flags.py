"""Command-line flags generated from configuration dataclasses (their one source).

Each field becomes `--PREFIX.FIELD-NAME` (dashes for underscores) with its type, its default and
its source comment as help, so a field added to a config is a flag at once and no default is
copied by hand. A field whose type has no command-line form raises `TypeError` unless it is
skipped explicitly: no field is dropped silently.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

_FIELD_LINE = re.compile(r"^(\s+)(\w+)\s*:[^#]*?(?:#\s*(.*))?$")
_COMMENT_LINE = re.compile(r"^(\s+)#\s?(.*)$")


def field_comments(cls: type) -> dict[str, str]:
    """The trailing comment of each field (with its continuation lines) in the class source."""
    try:
        lines = inspect.getsource(cls).splitlines()
    except (OSError, TypeError):
        return {}
    names = {f.name for f in dataclasses.fields(cls)}
    out: dict[str, str] = {}
    current: str | None = None
    indent = ""
    for line in lines:
        field_match = _FIELD_LINE.match(line)
        if field_match and field_match.group(2) in names:
            current, indent = field_match.group(2), field_match.group(1)
            out[current] = (field_match.group(3) or "").strip()
            continue
        comment = _COMMENT_LINE.match(line)
        if current is not None and comment and comment.group(1) == indent:
            out[current] = f"{out[current]} {comment.group(2).strip()}".strip()
            continue
        current = None
    return out


@dataclass(frozen=True)
class FlagSpec:
    """One generated flag: the dataclass field it sets and the argparse destination."""

    field: str
    dest: str
    option: str


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        if len(rest) == 1:
            return rest[0], True
    return tp, False


def _argument_kwargs(tp: Any, name: str) -> dict[str, Any]:
    """argparse keywords for a field type; TypeError for types with no command-line form."""
    inner, _optional = _unwrap_optional(tp)
    origin = typing.get_origin(inner)
    if inner is bool:
        return {"action": argparse.BooleanOptionalAction}
    if inner is str:
        return {"type": str, "metavar": name.upper()}
    if inner in (int, float):
        return {"type": inner, "metavar": inner.__name__.upper()}
    if origin is Literal:
        values = typing.get_args(inner)
        return {"type": type(values[0]), "choices": values}
    if origin is tuple:
        items = typing.get_args(inner)
        if len(items) == 2 and items[1] is Ellipsis and items[0] in (int, float, str):
            return {"type": items[0], "nargs": "+", "metavar": items[0].__name__.upper()}
        if items and all(i in (int, float, str) for i in items) and len(set(items)) == 1:
            metavar = ("LOW", "HIGH") if len(items) == 2 else ("X", "Y", "Z")[: len(items)]
            if len(items) > 3:
                metavar = tuple(f"V{i}" for i in range(len(items)))
            return {"type": items[0], "nargs": len(items), "metavar": metavar}
    raise TypeError(f"field {name!r} of type {tp!r} has no command-line form; skip it explicitly")


def _format_default(value: Any) -> str:
    if isinstance(value, tuple):
        return " ".join(str(v) for v in value)
    return str(value)


def add_dataclass_flags(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    cls: type,
    *,
    prefix: str = "",
    skip: Sequence[str] = (),
    defaults: Mapping[str, str] | None = None,
    choices: Mapping[str, Sequence[str]] | None = None,
    aliases: Mapping[str, Sequence[str]] | None = None,
) -> list[FlagSpec]:
    """Add one flag per field of dataclass `cls`; returns what `collect` needs.

    defaults: text shown as a field's default instead of the dataclass default (e.g. per
    preset); choices: valid values for `str` fields; aliases: extra option strings.
    Flags left out of the command line are absent from the namespace (argparse.SUPPRESS), so
    only what the user typed overrides the configuration.
    """
    hints = typing.get_type_hints(cls)
    comments = field_comments(cls)
    specs: list[FlagSpec] = []
    for f in dataclasses.fields(cls):
        if f.name in skip or not f.init:
            continue
        kwargs = _argument_kwargs(hints[f.name], f.name)
        if choices and f.name in choices:
            kwargs["choices"] = tuple(choices[f.name])
            kwargs.pop("metavar", None)
        if defaults and f.name in defaults:
            shown = defaults[f.name]
        elif f.default is not dataclasses.MISSING:
            shown = _format_default(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            shown = _format_default(f.default_factory())
        else:
            shown = "required"
        text = comments.get(f.name, "")
        help_text = f"{text} (default: {shown})" if text else f"(default: {shown})"
        dest = f"{prefix}{f.name}".replace(".", "__")
        option = "--" + f"{prefix}{f.name}".replace("_", "-")
        options = [option, *((aliases or {}).get(f.name, ()))]
        parser.add_argument(
            *options,
            dest=dest,
            default=argparse.SUPPRESS,
            help=help_text.replace("%", "%%"),
            **kwargs,
        )
        specs.append(FlagSpec(f.name, dest, option))
    return specs


def collect(args: argparse.Namespace, specs: Sequence[FlagSpec]) -> dict[str, Any]:
    """The fields the user set on the command line (tuples for multi-value flags)."""
    out: dict[str, Any] = {}
    for spec in specs:
        if hasattr(args, spec.dest):
            value = getattr(args, spec.dest)
            out[spec.field] = tuple(value) if isinstance(value, list) else value
    return out
