"""The Grapher on Ray: failures, scheduling and playing in the driver never change the
hyperedge weights; batched chunks play the episodes the one-hyperedge path plays."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import ray

from hola_ray.config.scenario import PursuitConfig, TeamChangeConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.learned import MLPPolicy, random_export
from hola_ray.population.evaluators import (
    EvaluatorPool,
    chunks,
    evaluate_team,
    evaluate_teams,
    team_config,
)
from hola_ray.population.grapher import evaluate_edges, evaluate_edges_here
from hola_ray.population.state import edge_seed

ENV = PursuitConfig(horizon=150)
NODES = range(5)
EDGES = list(itertools.combinations(NODES, 3))  # 10 hyperedges
EPISODES = 6
PARTS = 4  # two chunks queued on each of the two actors


EXPORTS = {node: random_export(ENV.obs_dim, seed=node, bias_scale=0.5) for node in NODES}


def seed_of(edge):
    return edge_seed(0, 1, edge)


def run(pool, on_result=None):
    return evaluate_edges(
        EDGES,
        pool,
        ray.put(EXPORTS),
        EPISODES,
        seed_of=seed_of,
        parts=PARTS,
        progress=False,
        on_result=on_result,
    )


@pytest.fixture(scope="module")
def pool(ray_session):
    """Two evaluation actors, shared by the tests (each actor's start costs seconds)."""
    actors = EvaluatorPool(ENV, workers=2)
    yield actors
    actors.shutdown()


@pytest.fixture(scope="module")
def baseline(pool):
    results, stats = run(pool)
    assert stats.retries == 0
    return results


def test_hyperedges_are_cut_into_chunks_by_the_config_alone():
    assert chunks(EDGES, 2) == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]]
    assert chunks(EDGES, 3) == [[0, 1, 2], [3, 4, 5, 6], [7, 8, 9]]
    assert chunks(EDGES[:1], 4) == [[0]]  # never an empty chunk
    assert sum(chunks(EDGES, 7), []) == list(range(len(EDGES)))


def test_the_weights_come_back_in_the_order_of_the_hyperedges(baseline):
    assert [r.nodes for r in baseline] == EDGES
    assert len({r.team_return for r in baseline}) > 1  # the members really differ
    assert all(r.episodes == EPISODES for r in baseline)


def test_the_driver_plays_the_same_weights_as_the_actors(baseline):
    results, stats = evaluate_edges_here(
        EDGES, EXPORTS, ENV, EPISODES, seed_of, parts=PARTS, progress=False
    )
    assert results == baseline
    assert (stats.edges, stats.episodes, stats.retries) == (len(EDGES), len(EDGES) * EPISODES, 0)


def test_killing_actors_mid_grapher_gives_the_same_weights(pool, baseline):
    killed = []

    def kill_the_other(chunk, results):
        if not killed:  # the other actor dies with a chunk in flight and one queued
            for k, actor in pool.actors().items():
                if k != chunk % 2:
                    ray.kill(actor, no_restart=True)
                    killed.append(k)

    results, stats = run(pool, on_result=kill_the_other)
    assert killed and stats.retries >= 1
    assert results == baseline
    # The pool has replaced the dead actor for the next generation.
    assert ray.get([a.ping.remote() for a in pool.actors().values()]) == [True, True]


def test_a_hyperedge_is_a_set_of_members():
    a = evaluate_team(ENV, (0, 1, 2), EXPORTS, EPISODES, seed=3)
    b = evaluate_team(ENV, (2, 0, 1), EXPORTS, EPISODES, seed=3)
    c = evaluate_team(ENV, (0, 1, 2), EXPORTS, EPISODES, seed=4)
    assert (a.team_return, a.length) == (b.team_return, b.length)
    assert (a.team_return, a.length) != (c.team_return, c.length)  # the seed matters
    assert np.isfinite(a.team_return)


def test_a_batched_chunk_plays_the_episodes_each_hyperedge_plays_alone():
    """One rollout of ten hyperedges against each hyperedge played alone on the reference
    path (every policy on every row of its seats, one forward pass each, as the Grapher
    played before it batched): the same episodes, so the same outcomes but where the
    stacked forward pass rounds an action's last bit differently and an episode parts."""
    env = PursuitConfig()  # the full horizon: episodes that end at different times
    episodes = 32
    batched = evaluate_teams(env, EDGES, EXPORTS, episodes, [seed_of(e) for e in EDGES])
    same = total = 0
    for edge, result in zip(EDGES, batched, strict=True):
        seed = seed_of(edge)
        rng = np.random.default_rng(seed)
        assignment = np.stack([rng.permutation(3) for _ in range(episodes)])
        alone = rollout(
            env,
            [MLPPolicy(env, EXPORTS[v]) for v in sorted(edge)],
            episodes,
            assignment=assignment,
            episode_seeds=episode_seeds(seed, episodes),
            batched=False,
        )
        assert result.nodes == edge and result.episodes == episodes
        assert abs(result.success - alone.success.mean()) <= 2 / episodes
        assert abs(result.length - alone.length.mean()) <= 0.05 * alone.length.mean()
        same += int(np.isclose(result.team_return, alone.team_return.mean(), rtol=1e-3))
        total += 1
    assert same >= 0.8 * total, f"{same} of {total} hyperedges kept their weight"


def test_a_monitor_whose_actor_died_is_played_here_to_the_same_figures(pool):
    """The population judged as a team (a monitor), submitted to evaluation actors that are
    dead: the driver plays it instead, to the figures it gives when played here."""
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.monitors import Monitoring

    config = RunConfig.from_dict(
        {
            "method": "hola",
            "env": {"horizon": 150},
            "grapher": {"episodes_per_edge": EPISODES},
            "validation": {"pool": "none"},
        }
    )
    here = Monitoring(config, None)
    here.submit(1, None, EXPORTS)
    expected = here.collect()
    assert expected[0] == 1 and "population_team_success" in expected[1]
    actors = pool.actors()
    for actor in actors.values():
        ray.kill(actor, no_restart=True)
    there = Monitoring(config, pool)
    there.submit(1, None, EXPORTS)

    def figures(done):  # wall times aside
        return done[0], {k: v for k, v in done[1].items() if not k.endswith("_s")}

    assert figures(there.collect()) == figures(expected)
    for k, actor in actors.items():  # the next test's pool is whole again
        pool.replace(k, actor)


def test_hyperedges_of_several_sizes_fly_as_teams_of_their_own_size():
    """A run whose teams change (5 seats observed, 2 to 5 flying): a hyperedge of k members
    flies as k pursuers from start to end in the run's slots, so one played among others of
    other sizes weighs what it weighs alone in that scenario; results keep the edges' order."""
    team = TeamChangeConfig(present=3, changes=2)
    env = PursuitConfig(n_pursuers=5, obs_pursuers=5, horizon=150, team=team)
    exports = {v: random_export(env.obs_dim, seed=v, bias_scale=0.5) for v in range(5)}
    edges = [(0, 1), (0, 1, 2, 3, 4), (1, 3, 4), (2, 4), (0, 2, 3, 4)]
    mixed = evaluate_teams(env, edges, exports, 4, [seed_of(e) for e in edges])
    assert [r.nodes for r in mixed] == edges
    for edge, result in zip(edges, mixed, strict=True):
        played = team_config(env, len(edge))
        assert (played.n_pursuers, played.pursuer_slots, played.team.open) == (len(edge), 5, False)
        (alone,) = evaluate_teams(played, [edge], exports, 4, [seed_of(edge)])
        assert (alone.nodes, alone.length, alone.success) == (edge, result.length, result.success)
        assert alone.team_return == pytest.approx(result.team_return, rel=1e-6)  # the stack's
    assert len({r.length for r in mixed}) == len(edges)  # five teams, five sets of episodes
    with pytest.raises(ValueError, match="a team holds 1..5 members"):
        evaluate_teams(env, [(0, 1, 2, 3, 4, 5)], {**exports, 5: exports[0]}, 1, [0])
