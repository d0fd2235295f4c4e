"""`--set KEY=VALUE` settings: dotted keys to task overrides and executor overrides.

Keys:
- `object.FIELD` (ObjectConfig: `object.frictionloss=2`, `object.radius=0.08`),
- `hand.FIELD` (HandConfig: `hand.translational_stiffness=8000`),
- `executor.FIELD` (a top-level ExecutorConfig field: `executor.threshold=1`) and
  `executor.GROUP.FIELD` (a field of one of its groups: `executor.limits.force_limit=40`,
  `executor.goal.travel=0.2`, `executor.guards.predictive_force=false`),
- `FIELD` (a top-level TaskConfig field: `force_limit=40`, `max_steps=80`).

Values: `true`/`false`, `none`/`null`, integers, floats (`1e-3`, `nan` is rejected by the
configs' own validation), comma-separated tuples (`0,1,0`), else the text itself. Unknown
prefixes and fields raise UnknownNameError listing the valid ones; bad values raise ConfigError
when the configs are built (`RunSpec` validates names at construction, `run` the values).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

from constraint_aware.control.executor_config import override_keys
from constraint_aware.errors import InvalidInputError, UnknownNameError
from constraint_aware.sim.hand import HandConfig
from constraint_aware.sim.objects import ObjectConfig
from constraint_aware.sim.tasks import TaskConfig

#: Dotted prefixes of `--set` keys, and the config each reaches.
PREFIXES = ("object", "hand", "executor")
#: TaskConfig fields that are nested configs: set their fields with a prefix instead.
_NESTED = ("object", "hand")

Value = object


@dataclass(frozen=True)
class Settings:
    """Parsed `--set` items: `TaskConfig.with_overrides` keys and `ExecutorConfig.with_overrides`
    keys (`threshold`, `limits__force_limit`)."""

    task_overrides: tuple[tuple[str, Value], ...] = ()
    executor_overrides: tuple[tuple[str, Value], ...] = ()

    def __bool__(self) -> bool:
        return bool(self.task_overrides or self.executor_overrides)


def field_names(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def valid_keys() -> list[str]:
    """Every key `parse_settings` accepts."""
    keys = [k for k in field_names(TaskConfig) if k not in _NESTED]
    keys += [f"object.{k}" for k in field_names(ObjectConfig)]
    keys += [f"hand.{k}" for k in field_names(HandConfig)]
    keys += [f"executor.{k.replace('__', '.')}" for k in override_keys()]
    return keys


def parse_value(text: str) -> Value:
    """A `--set` value: bool, None, int, float, a tuple of those (comma-separated), or text."""
    text = text.strip()
    if "," in text:
        return tuple(parse_value(part) for part in text.split(",") if part.strip() != "")
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def parse_settings(items: Sequence[str]) -> Settings:
    """`["object.mass=3", "executor.threshold=1", "force_limit=40"]` -> Settings.

    Raises InvalidInputError for an item without `=` or a repeated key, UnknownNameError for
    an unknown prefix or field (listing the valid ones)."""
    task: dict[str, Value] = {}
    executor: dict[str, Value] = {}
    seen: set[str] = set()
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InvalidInputError(f"--set {item!r}: expected KEY=VALUE, e.g. object.mass=3")
        if key in seen:
            raise InvalidInputError(f"--set {key}: given more than once")
        seen.add(key)
        value = parse_value(raw)
        prefix, dot, name = key.partition(".")
        if not dot:
            valid = [k for k in field_names(TaskConfig) if k not in _NESTED]
            if key not in valid:
                raise UnknownNameError("setting", key, valid_keys())
            task[key] = value
        elif prefix == "executor":
            override = name.replace(".", "__")
            if "__" in name or override not in override_keys():
                executor_keys = [k for k in valid_keys() if k.startswith("executor.")]
                raise UnknownNameError("setting", key, executor_keys)
            executor[override] = value
        elif prefix in _NESTED:
            cls = ObjectConfig if prefix == "object" else HandConfig
            if name not in field_names(cls):
                raise UnknownNameError("setting", key, valid_keys())
            task[f"{prefix}__{name}"] = value
        else:
            raise UnknownNameError("setting prefix", prefix, list(PREFIXES))
    return Settings(tuple(task.items()), tuple(executor.items()))
