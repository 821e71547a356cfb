"""The Grapher on Ray: worker count, failures and playing in the driver never change the
hyperedge weights."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import ray

from hola_ray.env.config import PursuitConfig
from hola_ray.policies.learned import random_export
from hola_ray.population.grapher import evaluate_edges, evaluate_edges_here
from hola_ray.population.member import MemberPool
from hola_ray.population.state import edge_seed

ENV = PursuitConfig(horizon=150)
NODES = range(5)
EDGES = list(itertools.combinations(NODES, 3))  # 10 hyperedges
EPISODES = 6


EXPORTS = {node: random_export(ENV.obs_dim, seed=node, bias_scale=0.5) for node in NODES}


def run(pool, workers, on_result=None):
    return evaluate_edges(
        EDGES,
        pool.ensure(EXPORTS),
        ray.put(EXPORTS),
        EPISODES,
        seed_of=lambda e: edge_seed(0, 1, e),
        workers=workers,
        progress=False,
        on_result=on_result,
    )


@pytest.fixture(scope="module")
def pool(ray_session):
    """One member actor per node, shared by the tests (each actor's start costs seconds)."""
    members = MemberPool(ENV.to_dict())
    yield members
    members.shutdown()


@pytest.fixture(scope="module")
def baseline(pool):
    results, stats = run(pool, workers=1)
    return results


def test_weights_do_not_depend_on_the_worker_count(pool, baseline):
    results, stats = run(pool, workers=2)
    assert results == baseline and stats.retries == 0
    assert [r.nodes for r in results] == EDGES
    assert len({r.team_return for r in results}) > 1  # the members really differ
    assert all(r.episodes == EPISODES for r in results)


def test_the_driver_plays_the_same_weights_as_the_member_actors(baseline):
    results, stats = evaluate_edges_here(
        EDGES, EXPORTS, ENV.to_dict(), EPISODES, lambda e: edge_seed(0, 1, e), progress=False
    )
    assert results == baseline
    assert (stats.edges, stats.episodes, stats.retries) == (len(EDGES), len(EDGES) * EPISODES, 0)


def test_killing_members_mid_grapher_gives_the_same_weights(pool, baseline):
    actors = pool.ensure(EXPORTS)
    killed = []

    def kill_all_but_one(k, result):
        if not killed:
            for node in list(NODES)[:-1]:
                ray.kill(actors[node], no_restart=True)
                killed.append(node)

    results, stats = run(pool, workers=2, on_result=kill_all_but_one)
    assert killed and stats.retries >= 1
    assert results == baseline
    # The pool replaces dead members for the next generation.
    fresh = pool.ensure(EXPORTS)
    assert ray.get([fresh[n].ping.remote() for n in NODES]) == list(NODES)


def test_a_hyperedge_is_a_set_of_members():
    from hola_ray.population.member import evaluate_team

    a = evaluate_team(ENV.to_dict(), (0, 1, 2), EXPORTS, EPISODES, seed=3)
    b = evaluate_team(ENV.to_dict(), (2, 0, 1), EXPORTS, EPISODES, seed=3)
    c = evaluate_team(ENV.to_dict(), (0, 1, 2), EXPORTS, EPISODES, seed=4)
    assert (a.team_return, a.length) == (b.team_return, b.length)
    assert (a.team_return, a.length) != (c.team_return, c.length)  # the seed matters
    assert np.isfinite(a.team_return)
