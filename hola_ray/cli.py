"""What every command line of the project shares: a bad input is one line and exit code 2."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr (`prog: error: …`) and exit code 2,
    without the usage block (`--help` still prints it)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def make_dir(path: Path, flag: str = "--out") -> None:
    """Create a run's or an experiment's folder before anything starts; one that cannot be
    (a path through a regular file, no permission, a full disk) is a ConfigError naming the
    path and why."""
    from hola_ray.env.config import ConfigError

    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as err:
        why = err.strerror or type(err).__name__
        raise ConfigError(f"{flag} {path} cannot be created: {why}") from None


def fail(message: str) -> int:
    """Print `error: message` as one line on stderr; the exit code 2 to return."""
    print(f"error: {' '.join(str(message).split())}", file=sys.stderr)
    return 2


def apply_sets(data: dict, assignments: list[str] | None) -> dict:
    """`data` (a config as a plain mapping) with each `section.field=value` of `--set`
    applied; the value is read as YAML (`1e5`, `[64, 64]`, `true`, `null`), and a dotted
    path may go deeper (`env.reward.approach=distance`). Raises ValueError naming the
    assignment when it is not `path=value`; the config's own checks judge the value."""
    import copy

    from hola_ray.env.checks import yaml_value

    out = copy.deepcopy(dict(data))
    for text in assignments or ():
        path, eq, raw = text.partition("=")
        keys = path.strip().split(".")
        if not eq or not all(keys):
            raise ValueError(f"--set {text!r}: write section.field=value (e.g. oracle.lr=1e-4)")
        try:
            value = yaml_value(raw)
        except ValueError as err:
            raise ValueError(f"--set {text!r}: {err}") from None
        node = out
        for key in keys[:-1]:
            inner = node.get(key)
            if inner is None:
                inner = node[key] = {}
            elif not isinstance(inner, dict):
                raise ValueError(f"--set {text!r}: {key} is not a section")
            node = inner
        node[keys[-1]] = value
    return out
