"""Hand-worked geometry and the rules of docs/contract.md §1 on the batched core."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hola_ray.env import BatchedPursuit, PursuitConfig

UP = math.pi / 2


def single(config, **state):
    env = BatchedPursuit(config, 1)
    env.reset(seeds=[0], initial_state={0: state})
    return env


def far_evaders(config):
    """Evaders parked in the top corners, away from everything in these tests."""
    return np.array([[0.4, 4.6], [3.2, 4.6]])[: config.n_evaders]


@pytest.mark.parametrize(("gap", "caught"), [(0.19, True), (0.21, False)])
def test_capture_distance(frozen_config, gap, caught):
    evaders = far_evaders(frozen_config)
    pursuers = np.array([[evaders[0, 0] + gap, 4.6], [1.5, 2.0], [2.5, 3.0]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=evaders)
    result = env.step(np.full((1, 3), 0.5))
    assert env.evader_alive[0, 0] == (not caught)
    assert env.captures[0] == int(caught)
    # the capture bonus of +10 goes to every pursuer (the approach term is ~1e-6 here)
    np.testing.assert_allclose(result.reward[0], 10.0 * caught, atol=1e-4)
    assert env.pursuer_active[0].all()


def test_captured_evader_reads_far_and_stops(frozen_config):
    evaders = far_evaders(frozen_config)
    pursuers = np.array([[evaders[0, 0] + 0.1, 4.6], [1.5, 2.0], [2.5, 3.0]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=evaders)
    env.step(np.full((1, 3), 0.5))
    where = env.evader_pos[0, 0].copy()
    for _ in range(5):
        env.step(np.full((1, 3), 0.5))
    np.testing.assert_array_equal(env.evader_pos[0, 0], where)
    np.testing.assert_array_equal(env.obs[0, :, 0:3], np.tile([2.0, 0.0, 0.0], (3, 1)))


def test_two_pursuers_closer_than_kappa_both_collide(frozen_config):
    pursuers = np.array([[1.5, 2.0], [1.69, 2.0], [3.0, 3.0]])  # 0.19 apart
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=far_evaders(frozen_config))
    result = env.step(np.full((1, 3), 0.5))
    assert result.disabled[0].tolist() == [True, True, False]
    assert env.pursuer_active[0].tolist() == [False, False, True]
    np.testing.assert_allclose(result.reward[0, :2], -10.0, atol=1e-4)
    assert env.collided[0] and not env.done[0]


def test_pursuers_at_021_do_not_collide(frozen_config):
    pursuers = np.array([[1.5, 2.0], [1.71, 2.0], [3.0, 3.0]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=far_evaders(frozen_config))
    result = env.step(np.full((1, 3), 0.5))
    assert not result.disabled.any() and not env.collided[0]


def test_pursuer_009_from_wall_collides(config):
    # 0.12 from the left wall heading −x, going straight: 0.12 − 0.3·0.1 = 0.09 < d_s = 0.1
    pursuers = np.array([[0.12, 2.0], [1.5, 3.0], [2.5, 3.0]])
    env = single(
        config,
        pursuer_pos=pursuers,
        pursuer_heading=np.array([math.pi, UP, UP]),
        evader_pos=far_evaders(config),
    )
    result = env.step(np.full((1, 3), 0.5))
    np.testing.assert_allclose(env.pursuer_pos[0, 0], [0.09, 2.0], atol=1e-12)
    assert result.disabled[0].tolist() == [True, False, False]


def test_pursuer_011_from_bar_is_safe_and_009_collides(frozen_config):
    # bar 3 spans y ∈ [2.45, 2.55] around x = 1.8
    for gap, hit in ((0.11, False), (0.09, True)):
        pursuers = np.array([[1.8, 2.45 - gap], [0.5, 3.0], [3.0, 3.0]])
        env = single(frozen_config, pursuer_pos=pursuers, evader_pos=far_evaders(frozen_config))
        assert env.step(np.full((1, 3), 0.5)).disabled[0, 0] == hit


def test_collided_pursuer_stops_and_episode_goes_on(config):
    pursuers = np.array([[0.12, 2.0], [1.5, 3.0], [2.5, 3.0]])
    env = single(
        config,
        pursuer_pos=pursuers,
        pursuer_heading=np.array([math.pi, UP, -UP]),
        evader_pos=far_evaders(config),
    )
    env.step(np.full((1, 3), 0.5))
    stopped = env.pursuer_pos[0, 0].copy()
    for _ in range(10):
        result = env.step(np.array([[1.0, 0.5, 0.5]]))
        assert result.reward[0, 0] == 0.0
    np.testing.assert_array_equal(env.pursuer_pos[0, 0], stopped)
    assert not env.done[0] and env.t[0] == 11


def test_disabled_pursuer_is_an_obstacle_not_a_teammate(frozen_config):
    # P0 sits 0.09 from the left wall and collides; P1, 0.31 to its right heading +y, then
    # sees it as its nearest obstacle point (the wall is 0.4 away) at bearing π − π/2 = +π/2.
    pursuers = np.array([[0.09, 2.0], [0.4, 2.0], [3.0, 3.0]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=far_evaders(frozen_config))
    assert env.step(np.full((1, 3), 0.5)).disabled[0].tolist() == [True, False, False]
    obs = env.obs[0]
    assert obs[1, 8:10].tolist() == [2.0, 0.0]  # P1's reading of teammate P0: unobserved
    assert obs[1, 6] == pytest.approx(0.31 / 5, abs=1e-6)
    assert obs[1, 7] == pytest.approx(0.5, abs=1e-6)


def test_all_evaders_caught_ends_with_success(frozen_config):
    evaders = far_evaders(frozen_config)
    pursuers = np.array([[evaders[0, 0] + 0.1, 4.6], [evaders[1, 0] - 0.1, 4.6], [1.8, 2.0]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=evaders)
    result = env.step(np.full((1, 3), 0.5))
    assert result.terminated[0] and not result.truncated[0] and env.done[0]
    metrics = env.episode_metrics(0)
    assert metrics["success"] and not metrics["collision"] and metrics["length"] == 1
    np.testing.assert_allclose(result.reward[0], 20.0, atol=1e-4)


def test_all_pursuers_disabled_ends_without_success(frozen_config):
    pursuers = np.array([[1.5, 2.0], [1.6, 2.0], [1.55, 2.1]])
    env = single(frozen_config, pursuer_pos=pursuers, evader_pos=far_evaders(frozen_config))
    result = env.step(np.full((1, 3), 0.5))
    assert result.terminated[0]
    assert env.episode_metrics(0) == {
        "success": False,
        "collision": True,
        "length": 1,
        "captures": 0,
        "team_return": pytest.approx(-30.0, abs=1e-3),
    }


def test_truncation_at_horizon():
    config = dataclasses.replace(PursuitConfig(), horizon=5)
    env = BatchedPursuit(config, 3)
    env.reset(seeds=[1, 2, 3])
    flags = [env.step(np.full((3, 3), 0.5)).truncated.copy() for _ in range(5)]
    assert not np.any(flags[:4]) and flags[4].all()
    assert env.t.tolist() == [5, 5, 5] and not env.success.any()


def test_nan_actions_raise_and_out_of_range_are_clipped(config):
    env = BatchedPursuit(config, 2)
    env.reset(seeds=[5, 5])
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([[0.5, np.nan, 0.5], [0.5, 0.5, 0.5]]))
    env.step(np.array([[7.0, -3.0, 0.5], [1.0, 0.0, 0.5]]))
    np.testing.assert_array_equal(env.pursuer_pos[0], env.pursuer_pos[1])
    np.testing.assert_array_equal(env.obs[0], env.obs[1])


@pytest.mark.parametrize("mode", ["distance", "own_move"])
def test_approach_reward_is_the_distance_gained(config, mode):
    """`distance`: d_now after both moves (docs/contract.md §1); `own_move`: from the pursuer's new
    position to where the evader was, so an evader's escape costs the pursuer nothing."""
    reward = dataclasses.replace(config.reward, approach=mode)
    env = BatchedPursuit(dataclasses.replace(config, reward=reward), 4)
    env.reset(seeds=[11, 12, 13, 14])
    rng = np.random.default_rng(0)
    for _ in range(50):
        before_p = env.pursuer_pos.copy()
        before_e = env.evader_pos.copy()
        alive = env.evader_alive.copy()
        active = env.pursuer_active.copy()
        captures = env.captures.copy()
        result = env.step(rng.random((4, 3)))
        d_prev = np.linalg.norm(before_e[:, None] - before_p[:, :, None], axis=-1)
        evaders = env.evader_pos if mode == "distance" else before_e
        d_now = np.linalg.norm(evaders[:, None] - env.pursuer_pos[:, :, None], axis=-1)
        approach = ((d_prev - d_now) / 0.3 * alive[:, None]).sum(-1)
        expected = approach + 10.0 * (env.captures - captures)[:, None] - 10.0 * result.disabled
        np.testing.assert_allclose(result.reward, expected * active, atol=1e-9)


def test_the_common_reward_gives_every_live_pursuer_the_teams_mean(config):
    """`reward.shared`: the same episodes as with each pursuer's own terms (the reward does
    not steer the dynamics), and every pursuer active at the start of a step, one the step
    disables included, receives the mean of the pursuers' own rewards; the others 0."""
    reward = dataclasses.replace(config.reward, obstacle_penalty=0.5, teammate_penalty=0.5)
    own = BatchedPursuit(dataclasses.replace(config, reward=reward), 8)
    shared_reward = dataclasses.replace(reward, shared=True)
    shared = BatchedPursuit(dataclasses.replace(config, reward=shared_reward), 8)
    seeds = list(range(30, 38))
    own.reset(seeds=seeds)
    shared.reset(seeds=seeds)
    rng = np.random.default_rng(1)
    crashed_mid_episode = 0
    for _ in range(300):
        active = own.pursuer_active.copy() & ~own.done[:, None]
        actions = rng.random((8, 3))
        mine, ours = own.step(actions), shared.step(actions)
        np.testing.assert_array_equal(own.pursuer_pos, shared.pursuer_pos)
        team = mine.reward.sum(axis=1, keepdims=True) / 3
        np.testing.assert_allclose(ours.reward, np.where(active, team, 0.0), atol=1e-12)
        crashed_mid_episode += int((mine.disabled & ~own.done[:, None]).any())
    assert crashed_mid_episode > 0  # the disabled-this-step rule was exercised


def test_reset_options_validate(config):
    env = BatchedPursuit(config, 1)
    with pytest.raises(ValueError, match="inside the arena"):
        env.reset(initial_state={0: {"evader_pos": np.array([[4.0, 1.0], [1.0, 1.0]])}})
    with pytest.raises(ValueError, match="shape"):
        env.reset(initial_state={0: {"pursuer_heading": np.zeros(2)}})
    with pytest.raises(ValueError, match="unknown initial-state"):
        env.reset(initial_state={0: {"pursuer_speed": 1.0}})


def test_proximity_penalties(frozen_config):
    """Pursuer 0 sits 0.12 m from the left wall (inside the 0.15 m obstacle reach, outside
    the 0.1 m safe radius); pursuers 1 and 2 are 0.25 apart (inside the 0.3 m teammate
    reach, outside κ = 0.2). With obstacle_penalty 2 and teammate_penalty 0.5 the rewards
    drop by exactly 2, 0.5 and 0.5 against the default reward, which has no penalties."""
    pursuers = np.array([[0.12, 2.0], [1.5, 2.0], [1.75, 2.0]])
    evaders = far_evaders(frozen_config)
    base = single(frozen_config, pursuer_pos=pursuers, evader_pos=evaders)
    reward = dataclasses.replace(frozen_config.reward, obstacle_penalty=2.0, teammate_penalty=0.5)
    shaped = single(
        dataclasses.replace(frozen_config, reward=reward), pursuer_pos=pursuers, evader_pos=evaders
    )
    plain = base.step(np.full((1, 3), 0.5)).reward[0].copy()
    result = shaped.step(np.full((1, 3), 0.5))
    np.testing.assert_allclose(result.reward[0] - plain, [-2.0, -0.5, -0.5], atol=1e-12)
    assert not result.disabled.any()


def test_graded_teammate_penalty(frozen_config):
    """`reward.teammate_graded`: pursuers 1 and 2 fly in parallel 0.25 m apart, so with a
    0.4 m reach the penalty is 0.5 · (0.4 − 0.25) / (0.4 − κ) = 0.375 each, not 0.5;
    pursuer 0, 1.35 m away, pays nothing."""
    pursuers = np.array([[0.3, 2.0], [1.5, 2.0], [1.75, 2.0]])
    evaders = far_evaders(frozen_config)
    base = single(frozen_config, pursuer_pos=pursuers, evader_pos=evaders)
    graded = dataclasses.replace(
        frozen_config.reward, teammate_penalty=0.5, teammate_distance=0.4, teammate_graded=True
    )
    shaped = single(
        dataclasses.replace(frozen_config, reward=graded), pursuer_pos=pursuers, evader_pos=evaders
    )
    plain = base.step(np.full((1, 3), 0.5)).reward[0].copy()
    result = shaped.step(np.full((1, 3), 0.5))
    np.testing.assert_allclose(result.reward[0] - plain, [0.0, -0.375, -0.375], atol=1e-9)


def test_observed_headings_follow_the_unchanged_observation(frozen_config):
    """`observe_headings`: the observation's first entries are the plain layout's, bit for
    bit; then each other pursuer's heading relative to the observer's / π, in seat order,
    0 for a teammate beyond d_p or disabled."""
    headings = dataclasses.replace(frozen_config, observe_headings=True)
    # pursuer 2 sits 2.5 m from pursuer 0 (beyond d_p = 2), 1.5 m from pursuer 1
    pursuers = np.array([[0.5, 1.6], [1.5, 2.0], [3.0, 2.0]])
    state = {
        "pursuer_pos": pursuers,
        "pursuer_heading": np.array([UP, 0.0, math.pi * 0.75]),
        "evader_pos": far_evaders(frozen_config),
    }
    plain, seen = single(frozen_config, **state), single(headings, **state)
    base = frozen_config.obs_dim
    assert seen.obs.shape[-1] == base + 2
    np.testing.assert_array_equal(seen.obs[..., :base], plain.obs)
    expected = [
        [(0.0 - UP) / math.pi, 0.0],  # pursuer 0: pursuer 1, then pursuer 2 (too far)
        [UP / math.pi, 0.75],  # pursuer 1: pursuers 0 and 2
        [0.0, -0.75],  # pursuer 2: pursuer 0 (too far), pursuer 1
    ]
    np.testing.assert_allclose(seen.obs[0, :, base:], expected, atol=1e-6)
    low, high = seen.layout.bounds()
    assert (low[base:] == -1).all() and (high[base:] == 1).all()
