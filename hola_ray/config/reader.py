"""The one config checker every config of the project is read with (run, experiment,
scenario, pool and D3QN configs): YAML read as numbers where YAML 1.1 would leave strings,
each value checked against its field's annotation before its range, and every error one
`ConfigError` that names the field (and, through `located`, the file and its line)."""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml


class ConfigError(ValueError):
    """A configuration value is missing, unknown or outside its allowed range; `field` is
    its dotted name when one field is at fault (to find its line in a YAML file)."""

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field

    def within(self, section: str) -> ConfigError:
        """The same error for a config nested under `section` (e.g. env.reward.capture)."""
        message = str(self)
        if self.field and message.startswith(self.field):
            message = f"{section}.{message}"
        return ConfigError(message, f"{section}.{self.field}" if self.field else section)


def require(ok: bool, name: str, allowed: str, value: Any) -> None:
    """Raise `ConfigError` naming the field and its allowed range unless `ok`."""
    if not ok:
        raise ConfigError(f"{name} must be {allowed}, got {value!r}", name.split(" (")[0])


def positive_int(
    section: str, obj: Any, *names: str, minimum: int = 1, maximum: int | None = None
) -> None:
    """`require` each field of `obj` to be an integer >= `minimum` (not a bool) and, when
    `maximum` is given, at most that (a size past it is a typo, not a run)."""
    for name in names:
        value = getattr(obj, name)
        is_int = isinstance(value, int) and not isinstance(value, bool)
        if is_int and maximum is not None and value > maximum:
            require(False, f"{section}.{name}", f"an integer in [{minimum}, {maximum:,}]", value)
        require(is_int and value >= minimum, f"{section}.{name}", f"an integer >= {minimum}", value)


def widths(name: str, value: Any, allow_empty: bool = False) -> None:
    """`require` a list of hidden-layer widths: at most 16 layers of 1 … 65,536 units."""
    ok = (allow_empty or len(value) > 0) and len(value) <= 16
    ok = ok and all(isinstance(h, int) and not isinstance(h, bool) for h in value)
    ok = ok and all(1 <= h <= 65_536 for h in value)
    require(ok, name, "a list of at most 16 layer widths in [1, 65,536]", value)


def finite_in(section: str, obj: Any, name: str, low: float, high: float, allowed: str) -> None:
    """`require` a field of `obj` to be a finite number in [low, high]."""
    value = getattr(obj, name)
    ok = isinstance(value, int | float) and math.isfinite(value) and low <= value <= high
    require(ok, f"{section}.{name}", allowed, value)


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader that also reads 1e5 and 3e-4 as numbers (YAML 1.1, which
    PyYAML follows, wants a dot: 1.0e5)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def load_yaml(path: str | Path) -> Any:
    """A config file's content; malformed YAML is one `ConfigError` with file and line."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"config file {path} does not exist")
    text = path.read_text()
    try:
        return yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ConfigError(f"{where}: not valid YAML: {problem}") from None


def line_of(path: str | Path, field: str | None) -> int | None:
    """The line of a dotted field (`oracle.lr`) in a YAML file, or of its nearest section
    present there; None when it is not in the file."""
    if not field:
        return None
    try:
        node = yaml.compose(Path(path).read_text(), Loader=_Loader)
    except yaml.YAMLError:
        return None
    line = None
    for key in field.split("."):
        if not isinstance(node, yaml.MappingNode):
            break
        match = next((kv for kv in node.value if kv[0].value == key), None)
        if match is None:
            break
        line = match[0].start_mark.line + 1
        node = match[1]
    return line


def yaml_value(text: str) -> Any:
    """One value written as YAML, read as config files are (1e5 is a number); ValueError
    when it is not YAML."""
    try:
        return yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as err:
        raise ValueError(f"not a YAML value ({getattr(err, 'problem', err)})") from None


def located(err: ConfigError, path: str | Path) -> ConfigError:
    """`err` prefixed with the file and the line of its field (when the file has it)."""
    line = line_of(path, err.field)
    return ConfigError(f"{path}{f':{line}' if line else ''}: {err}", err.field)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def consume_fields(cls: type, data: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    """`data` as keyword arguments of the dataclass `cls`; unknown keys are an error. A
    whole float (1e5) given for an integer field becomes that integer."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ConfigError(
            f"unknown key(s) {', '.join(prefix + k for k in unknown)}; "
            f"allowed: {', '.join(sorted(names))}",
            prefix + unknown[0],
        )
    hints = typing.get_type_hints(cls)
    return {key: checked(hints[key], value, prefix + key) for key, value in data.items()}


def checked(hint: Any, value: Any, name: str, field_name: str | None = None) -> Any:
    """`value` as the field's annotation `hint` wants it, or one `ConfigError` naming the
    field: a count is an int (a whole float such as 1e5 becomes one; a bool, 1.5 or "3" is
    an error), a number an int or float but not a bool, a string, NaN or ±inf, a flag a
    bool, a list a tuple (its items checked the same way), a section a mapping (not null).
    Ranges are each config's own checks. `field_name`: the field an item of a list
    belongs to, for the error's location."""

    def fail(wanted: str) -> None:
        raise ConfigError(f"{name} must be {wanted}, got {value!r}", field_name or name)

    origin = typing.get_origin(hint)
    if hint is bool:
        if not isinstance(value, bool):
            fail("true or false")
        return value
    if hint is int:
        if isinstance(value, float) and math.isfinite(value) and value.is_integer():
            return int(value)
        if not isinstance(value, int) or isinstance(value, bool):
            fail("an integer")
        return value
    if hint is float:
        if not _is_number(value) or not math.isfinite(value):
            fail("a finite number")
        return value
    if hint is str:
        if not isinstance(value, str):
            fail("a string")
        return value
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(hint)
        if value is None and type(None) in options:
            return None
        inner = [o for o in options if o is not type(None)]
        if len(inner) == 1:
            return checked(inner[0], value, name, field_name)
        for option in inner[:-1]:  # the first that takes the value; the last one's error else
            try:
                return checked(option, value, name, field_name)
            except ConfigError:
                continue
        return checked(inner[-1], value, name, field_name)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            fail("a list")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            items = [args[0]] * len(value)
        else:
            items = list(args)
            if len(value) != len(items):
                fail(f"a list of {len(items)} items")
        return tuple(  # the frozen dataclasses hold tuples, however the YAML wrote the list
            checked(h, v, f"{name}[{i}]", field_name or name)
            for i, (h, v) in enumerate(zip(items, value, strict=True))
        )
    if dataclasses.is_dataclass(hint):
        if not isinstance(value, Mapping):
            fail("a mapping")
        return value
    return value
