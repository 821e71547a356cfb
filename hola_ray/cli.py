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
    from hola_ray.config.reader import ConfigError

    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as err:
        why = err.strerror or type(err).__name__
        raise ConfigError(f"{flag} {path} cannot be created: {why}") from None


def port(text: str) -> int:
    """argparse type of a TCP port: a whole number in 1–65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a port is a whole number, not {text!r}") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is in 1–65535, not {value}")
    return value


def require_free_port(port: int | None, flag: str) -> None:
    """A ConfigError when nothing of this machine could listen on `port` (another process
    holds it), checked before Ray starts: Ray would wait about 30 s for its metrics agent
    and end in its startup traceback. Nothing to check without a port, or on a cluster
    (RAY_ADDRESS: the nodes serve on their own ports)."""
    import os
    import socket

    from hola_ray.config.reader import ConfigError

    if port is None or os.environ.get("RAY_ADDRESS"):
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        # as a server binds: a port another process listens on is refused, one a finished
        # run left in TIME_WAIT is not
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("", port))
        except OSError as err:
            why = err.strerror or type(err).__name__
            raise ConfigError(f"{flag} {port}: {why}; choose a free port") from None


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

    from hola_ray.config.reader import yaml_value

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
