"""Evaluation actors: a run's hyperedges and monitors played in a few large batches.

A generation's hyperedges are cut into as many chunks as the run has evaluation actors
(`grapher.workers`), and each chunk is one vectorised rollout (`evaluate_teams`): every
episode of every hyperedge in it stepped at once, the learned members in one stacked
forward pass, finished episodes dropped from the forward passes. The same actors play the
figures that only monitor (validation, the population as a team) while the next
generation trains (`EvaluatorPool.submit`). An actor is started once per run, not once per
member, and its start (imports, the simulator's compiled kernels) overlaps the Oracle's.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import ray

from hola_ray.config.scenario import PursuitConfig, TeamChangeConfig
from hola_ray.population.state import EdgeResult
from hola_ray.process import pin_threads


def evaluate_team(
    config: PursuitConfig,
    team: Sequence[int],
    exports: Mapping[int, Mapping[str, Any]],
    episodes: int,
    seed: int,
) -> EdgeResult:
    """One hyperedge's weight: `episodes` episodes of the l policies of `team` (a chunk of
    one hyperedge, `evaluate_teams`)."""
    (result,) = evaluate_teams(config, [tuple(team)], exports, episodes, [seed])
    return result


def evaluate_teams(
    config: PursuitConfig,
    teams: Sequence[Sequence[int]],
    exports: Mapping[int, Mapping[str, Any]],
    episodes: int,
    seeds: Sequence[int],
) -> list[EdgeResult]:
    """The weights of several hyperedges, played as one rollout of `episodes` episodes each.

    Each episode of hyperedge k seats its l members in a random order over the pursuer
    slots (drawn from `seeds[k]`, as are its episodes), so no member is tied to a slot; a
    team is a set, so the order it is listed in does not matter. A hyperedge's episodes are
    the same whichever others share its rollout; its figures are the same to within the
    float rounding of the stacked forward pass. A team smaller than the scenario's, or one of
    a run whose team changes, flies as it is, from start to end (`team_config`); teams of
    several sizes are played one size at a time.
    """
    from hola_ray.evaluation.metrics import team_figures
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.evaluation.stats import episode_seeds
    from hola_ray.policies.learned import MLPPolicy

    sizes = sorted({len(team) for team in teams})
    if len(sizes) > 1:  # teams of several sizes (contract §6.2): each size its own rollout
        out: dict[int, EdgeResult] = {}
        for k in sizes:
            picked = [i for i, team in enumerate(teams) if len(team) == k]
            played = evaluate_teams(
                config, [teams[i] for i in picked], exports, episodes, [seeds[i] for i in picked]
            )
            out.update(zip(picked, played, strict=True))
        return [out[i] for i in range(len(teams))]
    for team in teams:
        if not 1 <= len(team) <= config.n_pursuers:
            raise ValueError(f"a team holds 1..{config.n_pursuers} members, got {list(team)}")
    config = team_config(config, len(teams[0])) if teams else config
    nodes = sorted({int(v) for team in teams for v in team})
    index = {v: k for k, v in enumerate(nodes)}
    policies = [MLPPolicy(config, exports[v], name=f"node_{v}") for v in nodes]
    assignment, played = [], []
    for team, seed in zip(teams, seeds, strict=True):
        members = np.array([index[v] for v in sorted(team)])
        rng = np.random.default_rng(seed)
        assignment.append(members[np.stack([rng.permutation(len(team)) for _ in range(episodes)])])
        played.append(episode_seeds(seed, episodes))
    result = rollout(
        config,
        policies,
        episodes * len(teams),
        assignment=np.concatenate(assignment),
        episode_seeds=np.concatenate(played),
        batch_size=max(1024, episodes * len(teams)),
    )
    return [
        EdgeResult(
            nodes=tuple(int(v) for v in team),
            episodes=episodes,
            **team_figures(result.part(k * episodes, (k + 1) * episodes)),
        )
        for k, team in enumerate(teams)
    ]


def team_config(config: PursuitConfig, size: int) -> PursuitConfig:
    """The scenario a hyperedge of `size` members is weighed in: `size` pursuers flying
    together from start to end, observed in the run's own slots, in its arenas; the run's
    scenario itself for its own fixed team."""
    if size == config.n_pursuers and not config.team.open:
        return config
    return dataclasses.replace(
        config,
        n_pursuers=size,
        obs_pursuers=config.pursuer_slots,
        team=TeamChangeConfig(),
    )


def chunks(edges: Sequence[tuple[int, ...]], count: int) -> list[list[int]]:
    """The indices of `edges` cut into at most `count` contiguous chunks of near-equal size:
    how a generation's hyperedges are batched (by the run's config, never by which actor is
    alive, so the weights do not depend on failures or scheduling)."""
    count = max(1, min(count, len(edges)))
    bounds = np.linspace(0, len(edges), count + 1).round().astype(int)
    return [list(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]


def lowest_priority() -> str:
    """Run this process only on CPU time nothing else wants: Linux's SCHED_IDLE policy,
    which any process may take for itself (elsewhere the highest niceness). Ray starts its
    workers at niceness 15: a niceness-19 process beside an env runner still takes about 30 %
    of their shared core (the scheduler's weights 15 against 36), and a generation's
    monitors slowed the Oracle's sampling by a tenth and more; SCHED_IDLE weighs 3.
    Returns the policy taken."""
    if hasattr(os, "sched_setscheduler") and hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
            return "SCHED_IDLE"
        except OSError:
            pass
    os.nice(max(19 - os.nice(0), 0))
    return f"niceness {os.nice(0)}"


@ray.remote(max_restarts=1, max_task_retries=1)
class Evaluator:
    """One evaluation process of a run: plays chunks of hyperedges and monitors. Each actor
    runs single-threaded, so parallelism comes from actors side by side."""

    def __init__(self, config: PursuitConfig):
        # below the Oracle's processes, from the start (its imports compete with the env
        # runner's): monitors played while a generation trains take the CPU time its env
        # runners and learner leave, not theirs
        self.priority = lowest_priority()
        os.environ.setdefault("OMP_NUM_THREADS", "1")
        pin_threads(1)
        self.config = config
        # Pay the simulator's compilation (or cache load) and the stacked forward's first
        # call now, while the run starts, rather than inside the first hyperedges.
        from hola_ray.policies.learned import random_export

        exports = {v: random_export(config.obs_dim, seed=v) for v in range(2)}
        team = (0,) * (config.n_pursuers - 1) + (1,)
        evaluate_teams(config, [team], exports, 1, [0])

    def ping(self) -> bool:
        return True

    def play_edges(
        self,
        teams: Sequence[Sequence[int]],
        exports: Mapping[int, Mapping[str, Any]],
        episodes: int,
        seeds: Sequence[int],
    ) -> list[EdgeResult]:
        """A chunk of hyperedges (`evaluate_teams`)."""
        return evaluate_teams(self.config, teams, exports, episodes, seeds)

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """`fn(*args)` in this process (a monitor: validation, the population as a team)."""
        return fn(*args)


class EvaluatorPool:
    """The driver's handles on a run's evaluation actors, started without waiting for them
    and recreated when one died."""

    def __init__(self, config: PursuitConfig, workers: int, run_name: str = ""):
        self.config = config
        self.workers = workers
        self.run_name = run_name
        self._actors: dict[int, ray.actor.ActorHandle] = {}
        self._turn = 0

    def start(self) -> None:
        """Start every missing actor (returns at once; a call waits for its actor)."""
        for k in range(self.workers):
            if k not in self._actors:
                name = f"evaluator:{self.run_name}:{k}" if self.run_name else None
                self._actors[k] = Evaluator.options(name=name, namespace="hola_ray").remote(
                    self.config
                )

    def actors(self) -> dict[int, ray.actor.ActorHandle]:
        """Every actor, started if missing."""
        self.start()
        return dict(self._actors)

    def replace(self, k: int, dead: ray.actor.ActorHandle) -> ray.actor.ActorHandle:
        """Actor k, started afresh if it is still `dead` (a call on it failed); another call
        that failed on the same actor finds it replaced already."""
        if self._actors.get(k) is dead:
            del self._actors[k]
            ray.kill(dead, no_restart=True)
        self.start()
        return self._actors[k]

    def submit(self, fn: Callable[..., Any], *args: Any) -> ray.ObjectRef:
        """`fn(*args)` on the next actor in turn, without waiting."""
        actors = self.actors()
        k = sorted(actors)[self._turn % len(actors)]
        self._turn += 1
        return actors[k].call.remote(fn, *args)

    def shutdown(self) -> None:
        for actor in self._actors.values():
            ray.kill(actor, no_restart=True)
        self._actors.clear()
