"""Who plays in the zero-shot evaluation: a learner loaded from a run directory or a policy
file, the teammate pools, and a researcher's own partners (`MODULE:CALLABLE`), each checked
on real observations. A bad input is one `EvaluationError` with one clear message."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.pools import POOLS, PoolError, load_pool
from hola_ray.evaluation.rollout import PolicyError
from hola_ray.policies.registry import load_policy, policy_file


class EvaluationError(RuntimeError):
    """A command line that cannot be evaluated: one clear message."""


def load_learner(path: Path, config: PursuitConfig) -> tuple[str, Any]:
    """(name, policy) of a run directory (its learner.pt) or an exported policy file."""
    try:
        policy = load_policy(path, config)
    except (ValueError, KeyError, RuntimeError) as err:
        raise EvaluationError(f"{policy_file(path)}: cannot load it as a learner: {err}") from err
    return policy.name, policy


def probe(policy: Any, name: str, config: PursuitConfig) -> None:
    """Play `policy` on a few real observations: its actions must be a finite [N] array."""
    env = BatchedPursuit(config, 4)
    obs = env.reset(seeds=np.arange(4)).reshape(-1, config.obs_dim)
    try:
        policy.reset(np.ones(len(obs), dtype=bool))
        actions = policy.act(obs)
    except Exception as err:  # noqa: BLE001 - a user's code: any failure is one line
        raise EvaluationError(f"{name}: act failed on {obs.shape} observations: {err!r}") from err
    try:
        PolicyError.check(name, actions, len(obs))
    except PolicyError as err:
        raise EvaluationError(str(err)) from err


def load_partner(spec: str, config: PursuitConfig) -> tuple[str, Any]:
    """`MODULE:CALLABLE` → (its name, what the callable returns for `config`)."""
    module_name, sep, attr = spec.rpartition(":")
    if not sep or not module_name or not attr.isidentifier():
        raise EvaluationError(f"--partner expects MODULE:CALLABLE, got {spec!r}")
    try:
        if module_name.endswith(".py") or "/" in module_name:
            file = Path(module_name)
            if not file.is_file():
                raise EvaluationError(f"--partner {spec}: no file {file}")
            loaded = importlib.util.spec_from_file_location(f"hola_partner_{file.stem}", file)
            module = importlib.util.module_from_spec(loaded)
            loaded.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as err:
        raise EvaluationError(f"--partner {spec}: cannot import {module_name}: {err}") from err
    except Exception as err:  # noqa: BLE001 - the module's own code raised on import
        raise EvaluationError(f"--partner {spec}: importing {module_name} failed: {err!r}") from err
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise EvaluationError(f"--partner {spec}: {module_name} has no callable {attr}")
    try:
        partner = factory(config)
    except Exception as err:  # noqa: BLE001 - a user's factory: any failure is one line
        raise EvaluationError(f"--partner {spec}: {attr}(config) raised {err!r}") from err
    for method in ("act", "reset"):
        if not callable(getattr(partner, method, None)):
            raise EvaluationError(f"--partner {spec}: what {attr} returns has no {method}()")
    probe(partner, f"--partner {spec}", config)
    return getattr(partner, "name", attr), partner


def pool_label(name: str) -> str:
    """How a pool is named in results: hot, het, or a pool folder's last part."""
    return name if name in POOLS else Path(name).name


def pools(names: Sequence[str], partners: Sequence[str], config: PursuitConfig):
    """Pool label (`pool_label`) → {member id → policy}, for --pool names/folders and the
    --partner pool."""
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        try:
            out[pool_label(name)] = load_pool(name, config)
        except PoolError as err:
            raise EvaluationError(str(err)) from err
    if partners:
        loaded = [load_partner(spec, config) for spec in partners]
        out["partners"] = {f"{n}-{k}": p for k, (n, p) in enumerate(loaded)}
    return out
