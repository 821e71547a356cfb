"""The Grapher: hyperedge evaluations fanned out over member actors with `ray.wait`, or
played one after another in the calling process (`evaluate_edges_here`, for populations
too small to be worth an actor per member).

At most `workers` evaluations are in flight. Each goes to the least busy member actor of
its hyperedge (any live member when none of them is). A failed evaluation (a member actor
that died) is sent again, with the same seed, to another member, so the weights do not
depend on failures or on scheduling.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import ray
from ray.exceptions import RayActorError

from hola_ray import interrupt
from hola_ray.population.member import evaluate_team
from hola_ray.population.state import EdgeResult
from hola_ray.progress import progress as progress_bar

MAX_ATTEMPTS = 4
"""Failures per hyperedge, beyond those explained by a member actor newly found dead,
before the Grapher gives up."""


@dataclass(frozen=True)
class GrapherStats:
    edges: int
    episodes: int
    wall_s: float
    retries: int

    @property
    def episodes_per_s(self) -> float:
        return self.episodes / max(self.wall_s, 1e-9)


def evaluate_edges(
    edges: Sequence[tuple[int, ...]],
    actors: Mapping[int, ray.actor.ActorHandle],
    exports_ref: ray.ObjectRef,
    episodes: int,
    seed_of: Callable[[tuple[int, ...]], int],
    workers: int,
    desc: str = "grapher",
    progress: bool = True,
    on_result: Callable[[int, EdgeResult], None] | None = None,
) -> tuple[list[EdgeResult], GrapherStats]:
    """Evaluate every hyperedge; results in the order of `edges`.

    actors: node → its Member actor (every node of every edge must have an export in
        `exports_ref`, an object-store dict node → export).
    seed_of: hyperedge → its evaluation seed.
    on_result: called with (edge index, result) as each evaluation comes back.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if not actors:
        raise ValueError("no member actors to evaluate on")
    results: list[EdgeResult | None] = [None] * len(edges)
    attempts = [0] * len(edges)
    failures = [0] * len(edges)
    busy = dict.fromkeys(actors, 0)
    dead: set[int] = set()
    pending: dict[ray.ObjectRef, tuple[int, int]] = {}  # ref → (edge index, actor node)
    queue = list(range(len(edges)))
    retries = 0
    start = time.perf_counter()

    def submit(k: int) -> None:
        live = [v for v in actors if v not in dead]
        if not live:
            raise RuntimeError("every member actor died during the Grapher")
        own = [v for v in edges[k] if v in actors and v not in dead]
        node = min(own or live, key=lambda v: busy[v])
        busy[node] += 1
        attempts[k] += 1
        ref = actors[node].evaluate.remote(edges[k], exports_ref, episodes, seed_of(edges[k]))
        pending[ref] = (k, node)

    with progress_bar(len(edges) * episodes, desc, "ep", enabled=progress) as bar:
        while queue or pending:
            interrupt.check()
            while queue and len(pending) < workers:
                submit(queue.pop(0))
            ready, _ = ray.wait(list(pending), num_returns=1)
            k, node = pending.pop(ready[0])
            busy[node] -= 1
            try:
                results[k] = ray.get(ready[0])
            except RayActorError as err:
                # A newly found dead actor is not the hyperedge's fault (each actor dies
                # once, so this is bounded); repeated failures on known-dead ones count.
                if node in dead:
                    failures[k] += 1
                dead.add(node)
                if failures[k] >= MAX_ATTEMPTS:
                    raise RuntimeError(f"hyperedge {edges[k]} failed {attempts[k]} times") from err
                retries += 1
                queue.insert(0, k)
                continue
            bar.update(episodes)
            if on_result is not None:
                on_result(k, results[k])
    wall = time.perf_counter() - start
    done = [r for r in results if r is not None]
    assert len(done) == len(edges)
    return done, GrapherStats(len(edges), len(edges) * episodes, wall, retries)


def evaluate_edges_here(
    edges: Sequence[tuple[int, ...]],
    exports: Mapping[int, Mapping[str, object]],
    env_config: Mapping[str, object],
    episodes: int,
    seed_of: Callable[[tuple[int, ...]], int],
    desc: str = "grapher",
    progress: bool = True,
) -> tuple[list[EdgeResult], GrapherStats]:
    """Evaluate every hyperedge in this process, one after another, with the seeds the
    member actors would use: the same weights as `evaluate_edges`, without an actor to
    start per member (`grapher.workers: 0`)."""
    results = []
    start = time.perf_counter()
    with progress_bar(len(edges) * episodes, desc, "ep", enabled=progress) as bar:
        for edge in edges:
            interrupt.check()
            results.append(evaluate_team(env_config, edge, exports, episodes, seed_of(edge)))
            bar.update(episodes)
    wall = time.perf_counter() - start
    return results, GrapherStats(len(edges), len(edges) * episodes, wall, 0)
