"""The Grapher: a generation's hyperedges weighed in a few large batches, fanned out over the
run's evaluation actors (`evaluate_edges`), or played in the calling process
(`evaluate_edges_here`, `grapher.workers: 0`).

The hyperedges are cut into `chunks` contiguous chunks (`hola_ray.population.evaluators.
chunks`: by the run's config, never by which actor is alive), each one vectorised rollout
(`evaluate_teams`). A chunk whose actor died is played again, with the same seeds, by a
fresh actor in its place, so the weights do not depend on failures or on scheduling; the
calling process plays the same chunks to the same weights.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import ray
from ray.exceptions import RayActorError

from hola_ray import interrupt
from hola_ray.config.scenario import PursuitConfig
from hola_ray.population.evaluators import EvaluatorPool, chunks, evaluate_teams
from hola_ray.population.state import EdgeResult
from hola_ray.progress import progress as progress_bar

MAX_ATTEMPTS = 4
"""Times a chunk may fail on a fresh actor before the Grapher gives up."""


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
    pool: EvaluatorPool,
    exports_ref: ray.ObjectRef,
    episodes: int,
    seed_of: Callable[[tuple[int, ...]], int],
    parts: int,
    desc: str = "grapher",
    progress: bool = True,
    on_result: Callable[[int, list[EdgeResult]], None] | None = None,
) -> tuple[list[EdgeResult], GrapherStats]:
    """Evaluate every hyperedge in `parts` chunks on the pool's actors; results in the order
    of `edges`.

    exports_ref: an object-store dict node → export holding every node of every edge.
    seed_of: hyperedge → its evaluation seed.
    on_result: called with (chunk index, its results) as each chunk comes back.
    """
    if not edges:
        return [], GrapherStats(0, 0, 0.0, 0)
    actors = pool.actors()
    if not actors:
        raise ValueError("no evaluation actors to play the hyperedges on")
    cut = chunks(edges, parts)
    results: list[EdgeResult | None] = [None] * len(edges)
    failures = [0] * len(cut)
    pending: dict[ray.ObjectRef, tuple[int, int, ray.actor.ActorHandle]] = {}  # ref → chunk, actor
    retries = 0
    start = time.perf_counter()

    def submit(c: int, k: int) -> None:
        teams = [edges[i] for i in cut[c]]
        actor = pool.actors()[k]
        ref = actor.play_edges.remote(teams, exports_ref, episodes, [seed_of(e) for e in teams])
        pending[ref] = (c, k, actor)

    keys = sorted(actors)
    for c in range(len(cut)):
        submit(c, keys[c % len(keys)])
    with progress_bar(len(edges) * episodes, desc, "ep", enabled=progress) as bar:
        while pending:
            interrupt.check()
            ready, _ = ray.wait(list(pending), num_returns=1)
            c, k, actor = pending.pop(ready[0])
            try:
                played = ray.get(ready[0])
            except RayActorError as err:
                failures[c] += 1
                if failures[c] >= MAX_ATTEMPTS:
                    teams = [edges[i] for i in cut[c]]
                    raise RuntimeError(f"hyperedges {teams} failed {failures[c]} times") from err
                retries += 1
                pool.replace(k, actor)
                submit(c, k)
                continue
            for i, result in zip(cut[c], played, strict=True):
                results[i] = result
            bar.update(len(played) * episodes)
            if on_result is not None:
                on_result(c, played)
    wall = time.perf_counter() - start
    done = [r for r in results if r is not None]
    assert len(done) == len(edges)
    return done, GrapherStats(len(edges), len(edges) * episodes, wall, retries)


def evaluate_edges_here(
    edges: Sequence[tuple[int, ...]],
    exports: Mapping[int, Mapping[str, object]],
    config: PursuitConfig,
    episodes: int,
    seed_of: Callable[[tuple[int, ...]], int],
    parts: int = 1,
    desc: str = "grapher",
    progress: bool = True,
) -> tuple[list[EdgeResult], GrapherStats]:
    """Evaluate every hyperedge in this process, chunk after chunk, with the chunks and seeds
    the actors would use: the same weights as `evaluate_edges`, without an actor to start
    (`grapher.workers: 0`)."""
    results: list[EdgeResult] = []
    start = time.perf_counter()
    with progress_bar(len(edges) * episodes, desc, "ep", enabled=progress) as bar:
        for part in chunks(edges, parts) if edges else []:
            interrupt.check()
            teams = [edges[i] for i in part]
            seeds = [seed_of(e) for e in teams]
            results += evaluate_teams(config, teams, exports, episodes, seeds)
            bar.update(len(teams) * episodes)
    wall = time.perf_counter() - start
    return results, GrapherStats(len(edges), len(edges) * episodes, wall, 0)


def weigh(
    edges: Sequence[tuple[int, ...]],
    exports: Mapping[int, Mapping[str, object]],
    config: PursuitConfig,
    pool: EvaluatorPool | None,
    episodes: int,
    seed_of: Callable[[tuple[int, ...]], int],
    parts: int,
    desc: str = "grapher",
    progress: bool = True,
) -> tuple[list[EdgeResult], dict[str, float]]:
    """A generation's hyperedges weighed on the pool's actors (`evaluate_edges`), or here
    without a pool (`evaluate_edges_here`): the results in the order of `edges`, and the
    Grapher's figures for the metrics row."""
    if pool is None:
        results, stats = evaluate_edges_here(
            edges, exports, config, episodes, seed_of, parts, desc, progress
        )
    else:
        results, stats = evaluate_edges(
            edges, pool, ray.put(dict(exports)), episodes, seed_of, parts, desc, progress
        )
    return results, {
        "grapher_edges": stats.edges,
        "grapher_s": round(stats.wall_s, 2),
        "grapher_episodes_per_s": round(stats.episodes_per_s, 1),
        "grapher_retries": stats.retries,
    }


def edge_summary(prefix: str, results: Sequence[EdgeResult]) -> dict[str, float]:
    """Episode-weighted means over hyperedges of every team figure, with the standard error
    across hyperedges: `<prefix>_<figure>` and `<prefix>_<figure>_se`."""
    import numpy as np

    from hola_ray.evaluation.metrics import TEAM

    n = np.array([r.episodes for r in results], dtype=np.float64)
    out: dict[str, float] = {}
    for m in TEAM:
        x = np.array([getattr(r, m.field) for r in results], dtype=np.float64)
        mean = float((x * n).sum() / n.sum())
        se = float(x.std(ddof=1) / np.sqrt(x.size)) if x.size > 1 else 0.0
        out[f"{prefix}_{m.name}"] = round(mean, 4)
        out[f"{prefix}_{m.name}_se"] = round(se, 4)
    return out
