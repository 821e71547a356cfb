"""A population member as a Ray actor: its frozen policy and batched hyperedge evaluation."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import ray

from hola_ray.population.state import EdgeResult
from hola_ray.progress import pin_threads


def evaluate_team(
    env_config: Mapping[str, Any],
    team: Sequence[int],
    exports: Mapping[int, Mapping[str, Any]],
    episodes: int,
    seed: int,
) -> EdgeResult:
    """Play `episodes` episodes of the l policies of `team` on the batched core.

    Each episode seats the team in a random order over the pursuer slots (drawn from
    `seed`), so no member is tied to a slot; the team is a set, so the order it is listed
    in does not matter. Returns the hyperedge's measured weight.
    """
    from hola_ray.env.config import PursuitConfig
    from hola_ray.evaluation.metrics import team_figures
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.policies.learned import MLPPolicy

    config = PursuitConfig.from_dict(env_config)
    if len(team) != config.n_pursuers:
        raise ValueError(f"a team holds {config.n_pursuers} members, got {list(team)}")
    seated = sorted(team)
    policies = [MLPPolicy(config, exports[node], name=f"node_{node}") for node in seated]
    rng = np.random.default_rng(seed)
    assignment = np.stack([rng.permutation(len(team)) for _ in range(episodes)])
    result = rollout(config, policies, episodes, assignment=assignment, seed=seed)
    return EdgeResult(nodes=tuple(int(v) for v in team), episodes=episodes, **team_figures(result))


@ray.remote(max_restarts=1, max_task_retries=1)
class Member:
    """One population node: holds its frozen policy's export and plays the hyperedges it
    is in. Each actor runs single-threaded, so parallelism comes from actors side by side."""

    def __init__(self, node: int, export: Mapping[str, Any], env_config: Mapping[str, Any]):
        os.environ.setdefault("OMP_NUM_THREADS", "1")
        pin_threads(1)
        self.node = node
        self.export = dict(export)
        self.env_config = dict(env_config)
        # Pay the simulator's compilation (or cache load) now, while the pool starts,
        # rather than inside the first hyperedge this member is given.
        from hola_ray.env.config import PursuitConfig

        team = [node] * PursuitConfig.from_dict(self.env_config).n_pursuers
        evaluate_team(self.env_config, team, {node: self.export}, 1, 0)

    def ping(self) -> int:
        return self.node

    def evaluate(
        self,
        team: Sequence[int],
        exports: Mapping[int, Mapping[str, Any]],
        episodes: int,
        seed: int,
    ) -> EdgeResult:
        """Evaluate a hyperedge holding this member; `exports` has the other members'."""
        own = {**exports, self.node: self.export} if self.node in team else exports
        return evaluate_team(self.env_config, team, own, episodes, seed)


class MemberPool:
    """The driver's handles on member actors, one per node, recreated when one died."""

    def __init__(self, env_config: Mapping[str, Any], run_name: str = ""):
        self.env_config = dict(env_config)
        self.run_name = run_name
        self.actors: dict[int, ray.actor.ActorHandle] = {}

    def ensure(self, exports: Mapping[int, Mapping[str, Any]]) -> dict[int, Any]:
        """A live actor for every node of `exports`; dead or missing ones are (re)made."""
        for node, export in exports.items():
            actor = self.actors.get(node)
            if actor is not None and not _alive(actor):
                actor = None
            if actor is None:
                name = f"member:{self.run_name}:{node:04d}" if self.run_name else None
                self.actors[node] = Member.options(name=name, namespace="hola_ray").remote(
                    node, export, self.env_config
                )
        ray.get([self.actors[node].ping.remote() for node in exports])
        return {node: self.actors[node] for node in exports}

    def remove(self, node: int) -> None:
        actor = self.actors.pop(node, None)
        if actor is not None:
            ray.kill(actor)

    def shutdown(self) -> None:
        for node in list(self.actors):
            self.remove(node)


def _alive(actor: Any) -> bool:
    try:
        ray.get(actor.ping.remote(), timeout=30)
        return True
    except (ray.exceptions.RayActorError, ray.exceptions.GetTimeoutError):
        return False
