"""benchmarks/crashes.py classifies every crash by what was within reach."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy

_spec = importlib.util.spec_from_file_location(
    "crashes", Path(__file__).parents[2] / "benchmarks" / "crashes.py"
)
crashes_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(crashes_module)


class Straight(Policy):
    """Never turns: from the spawn row (heading +y) straight up into whatever is above."""

    name = "straight"

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.full(len(self._check(obs)), 0.5)


def test_straight_flyers_hit_the_bars_above_them_and_never_each_other():
    config = PursuitConfig(n_pursuers=3, n_evaders=1)
    episodes, seed = 60, 9
    result = crashes_module.crashes(config, [Straight(config)] * 3, episodes, seed)
    # pursuers spawned under one of the two lowest bars (within the safe radius of its
    # ends) hit it within a few dozen steps, long before any evader comes near
    env = BatchedPursuit(config, episodes)
    env.reset(seeds=episode_seeds(seed, episodes))
    low_bars = [r for r in config.obstacles if r[1] < 1.5]
    x = env.pursuer_pos[..., 0]
    under = np.zeros_like(x, dtype=bool)
    for cx, _, w, _ in low_bars:
        under |= np.abs(x - cx) < w / 2 + config.safe_radius - 0.01
    assert under.sum() > 0
    assert result["crashes"]["mate"] == 0
    assert result["crashes"]["bar"] >= under.sum()
    assert result["crashes"]["wall"] > 0  # the others fly on to the top wall or a bar
    played = rollout(
        config, [Straight(config)] * 3, episodes, episode_seeds=episode_seeds(seed, episodes)
    )
    assert sum(result["crashes"].values()) == played.crashed.sum()


def test_a_disc_is_an_obstacle_where_straight_flyers_meet_one():
    """In the `blocks` arena, pursuers spawned under the disc fly into it: a `bar` (an
    obstacle), not a `wreck` (what a crash into a disc read as before discs counted)."""
    config = PursuitConfig(n_pursuers=3, n_evaders=1).in_arena("blocks")
    episodes, seed = 60, 9
    result = crashes_module.crashes(config, [Straight(config)] * 3, episodes, seed)
    env = BatchedPursuit(config, episodes)
    env.reset(seeds=episode_seeds(seed, episodes))
    x = env.pursuer_pos[..., 0]
    (cx, _, r), *_ = config.discs
    under_disc = np.abs(x - cx) < r + config.safe_radius - 0.01
    assert under_disc.sum() > 1
    # one straight flyer may meet a wreck, as in the paper's arena; never all under the disc
    assert result["crashes"]["wreck"] < under_disc.sum() and result["crashes"]["mate"] == 0
    assert result["crashes"]["bar"] >= under_disc.sum()


def test_greedy_copies_crash_mostly_into_each_other():
    config = PursuitConfig(n_pursuers=3, n_evaders=1)
    result = crashes_module.crashes(config, [Greedy(config)] * 3, 100, 3)
    counts = result["crashes"]
    assert counts["mate"] > counts["wall"] + counts["bar"] + counts["wreck"]
    assert sum(result["evaders_left_at_crash"]) == sum(counts.values())
    left = result["learner_mates_left_at_crash"]  # seat 0's crashes by teammates flying
    assert len(left) == 3 and sum(left) == sum(result["learner_crashes"].values())
    assert left[2] > 0  # copies that fly into each other: both teammates often still up


def test_flown_crashes_are_the_flown_rollouts_crashes(straight):
    pytest.importorskip("pybullet")
    from hola_ray.flight import Crazyflies

    config = PursuitConfig(n_pursuers=3, n_evaders=1, horizon=150)
    episodes, seed = 8, 9
    team = [straight] * 3
    flown = crashes_module.crashes(config, team, episodes, seed, Crazyflies)
    played = rollout(
        config,
        team,
        episodes,
        episode_seeds=episode_seeds(seed, episodes),
        dynamics=Crazyflies,
    )
    assert sum(flown["crashes"].values()) == played.crashed.sum() > 0
    assert flown["crashes"]["mate"] == 0  # flying straight up, side by side
