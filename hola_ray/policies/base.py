"""The one interface every pursuer policy sits behind (docs/contract.md §3).

A policy maps a batch of observations [N, obs_dim] to a batch of actions [N] in [0, 1],
so that any mix of policies can fill any pursuer slots. Policies that keep per-episode
state are bound to a fixed number of rows and clear the rows of `reset(mask)`; one object
placed in several seats plays as that many separate copies (`seated`).
"""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np

from hola_ray.config.scenario import PursuitConfig


class Policy(ABC):
    """A pursuer policy: observations [N, obs_dim] → actions [N] in [0, 1]."""

    name: str = "policy"

    def __init__(self, config: PursuitConfig) -> None:
        self.config = config
        self.layout = config.layout

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Actions [N] in [0, 1] for observations [N, obs_dim]."""

    def reset(self, mask: np.ndarray | None = None) -> None:  # noqa: B027 - stateless default
        """Forget the per-episode state of the rows in mask (all rows when None)."""

    def twin(self) -> Policy:
        """A policy that plays exactly as this one with per-row state of its own, for another
        seat (its weights shared). A policy that keeps no state is its own twin."""
        return self

    def _check(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.layout.dim:
            raise ValueError(
                f"{self.name} expects observations [N, {self.layout.dim}], got {obs.shape}"
            )
        return obs

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


def seated(policies: Sequence[Any]) -> list[Any]:
    """`policies` with every repeat of an object replaced by its twin, so that one object
    listed for several seats (`[d3qn_g] * 3`) plays as that many separate copies: a policy
    with per-row state (D3QN-G holds its pair for `decision_interval` steps) would otherwise
    have every seat overwrite the others' state. An object without `twin` (a `--partner`
    of the user's) is deep-copied."""
    out: list[Any] = []
    seen: set[int] = set()
    for policy in policies:
        if id(policy) in seen:
            make = getattr(policy, "twin", None)
            policy = make() if callable(make) else copy.deepcopy(policy)
        seen.add(id(policy))
        out.append(policy)
    return out
