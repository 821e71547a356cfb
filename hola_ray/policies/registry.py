"""Policies by name, for command lines and configs."""

from __future__ import annotations

from collections.abc import Callable

from hola_ray.env.config import PursuitConfig
from hola_ray.policies.apf import APFA
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy
from hola_ray.policies.vicsek import Vicsek

_FACTORIES: dict[str, Callable[[PursuitConfig], Policy]] = {
    "greedy": Greedy,
    "vicsek": Vicsek,
    **{f"apf-a-{k}": (lambda cfg, k=k: APFA(cfg, pair=k)) for k in range(24)},
}


def policy_names() -> list[str]:
    """Names `make_policy` accepts."""
    return list(_FACTORIES)


def make_policy(name: str, config: PursuitConfig) -> Policy:
    """The policy called `name` (case-insensitive) for this scenario."""
    key = name.lower()
    if key not in _FACTORIES:
        raise ValueError(f"unknown policy {name!r}; known: {', '.join(policy_names())}")
    return _FACTORIES[key](config)
