"""Hand-written teammates act on the observation alone, with hand-worked turns."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hola_ray.env import BatchedPursuit, PursuitConfig
from hola_ray.policies import APFA, APFConfig, Greedy, Vicsek, make_policy, policy_names
from hola_ray.policies.surround import Surround, SurroundConfig


def blank_obs(config: PursuitConfig, rows: int = 1) -> np.ndarray:
    """Observations with every evader captured, nothing near, no teammate seen."""
    lay = config.layout
    obs = np.zeros((rows, lay.dim), dtype=np.float32)
    for e in range(lay.n_evaders):
        obs[:, 3 * e] = config.unobserved_distance
    obs[:, lay.obstacle] = 1.0  # 5 m away
    for j in range(lay.n_pursuers - 1):
        obs[:, lay.teammates + 2 * j] = config.unobserved_distance
    return obs


def test_greedy_turns_toward_the_nearest_live_evader(config):
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.1, 0.0)  # evader 0: 2 m away, 18° to the left
    obs[0, 3:6] = (0.2, -0.5, 0.0)  # evader 1: 1 m away, 90° to the right → nearest
    # wanted turn −90° is beyond the 45° limit: full right turn, action 0
    assert Greedy(config).act(obs)[0] == 0.0
    obs[0, 3:6] = (0.3, -0.125, 0.0)  # now 1.5 m away at −22.5°: a = 0.5 − 22.5/90 = 0.25
    assert Greedy(config).act(obs)[0] == pytest.approx(0.25)


def test_greedy_sidesteps_a_near_obstacle_or_teammate(config):
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.0, 0.0)  # evader dead ahead
    obs[0, 6:8] = (0.25 / 5, 0.2)  # obstacle 0.25 m away, to the left
    # turn 20° right: a = 0.5 − 20/90
    assert Greedy(config).act(obs)[0] == pytest.approx(0.5 - 20 / 90, abs=1e-6)
    obs[0, 6:8] = (1.0, 0.0)
    obs[0, 8:10] = (0.2 / 5, -0.3)  # teammate 0.2 m away to the right → turn 20° left
    assert Greedy(config).act(obs)[0] == pytest.approx(0.5 + 20 / 90, abs=1e-6)


def test_no_live_evader_means_straight_on(config):
    for policy in (Greedy(config), Vicsek(config), APFA(config, 12), Surround(config)):
        assert policy.act(blank_obs(config))[0] == pytest.approx(0.5)


def test_apf_with_nothing_around_heads_for_the_evader(config):
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.1, 0.0)  # 18° left → a = 0.5 + 18/90 = 0.7
    assert APFA(config, 0).act(obs)[0] == pytest.approx(0.7, abs=1e-6)


def test_apf_grid_is_8_lambdas_by_3_etas(config):
    pairs = APFConfig().pairs
    assert len(pairs) == 24 and len({lam for lam, _ in pairs}) == 8
    assert len({eta for _, eta in pairs}) == 3
    # DACOOP-A's action a: η = (1e6, 1e7, 1e8)[a // 8] mm³, λ = (a mod 8)·4000/7 mm, in metres
    for a in range(24):
        lam, eta = APFA(config, a).lam, APFA(config, a).eta
        assert lam == pytest.approx((a % 8) * 4000 / 7 / 1000)
        assert eta == pytest.approx((1e6, 1e7, 1e8)[a // 8] * 1e-9)
    with pytest.raises(ValueError, match="pair must be in"):
        APFA(config, 24)


def test_apf_obstacle_repulsion_turns_away(config):
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.0, 0.0)  # evader dead ahead
    obs[0, 6:8] = (0.3 / 5, 0.1)  # obstacle 0.3 m ahead-left
    weak = APFA(config, 0).act(obs)[0]  # η = 0.001 m³
    strong = APFA(config, 16).act(obs)[0]  # η = 0.1 m³: wall following
    assert strong < weak < 0.5  # turns right, away from it, the more the stronger η


def test_vicsek_leads_a_crossing_evader(config):
    obs = blank_obs(config)
    # evader 1 m straight ahead running to the left (+90° relative): aim left of it
    obs[0, 0:3] = (0.2, 0.0, 0.5)
    assert Vicsek(config).act(obs)[0] > 0.5


def test_surround_alone_heads_straight_for_the_evader(config):
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.1, 0.0)  # 2 m away, 18° left; no teammate: a = 0.5 + 18/90
    assert Surround(config).act(obs)[0] == pytest.approx(0.7, abs=1e-6)


def test_surround_flanks_away_from_a_teammate_on_the_same_evader(config):
    """A teammate on the evader's far-left side (seen from the pursuer) pushes the pursuer's
    angle around the evader the other way: it bears right of the straight line, and more so
    the larger the flank; within `close` of the evader it goes straight."""
    obs = blank_obs(config)
    obs[0, 0:3] = (0.4, 0.0, 0.0)  # evader 2 m dead ahead
    # a teammate 2 m away at 20° left: 0.7 m left of the line to the evader, as near it
    obs[0, 6:8] = (1.0, 0.0)
    obs[0, 8:10] = (0.4, 20 / 180)
    straight = Surround(config, SurroundConfig(flank=0.0)).act(obs)[0]
    assert straight == pytest.approx(0.5, abs=1e-6)
    one = Surround(config, SurroundConfig(flank=1.0)).act(obs)[0]
    two = Surround(config, SurroundConfig(flank=2.0)).act(obs)[0]
    assert two < one < 0.5  # turns right, away from the teammate's side
    obs[0, 0:3] = (0.08, 0.0, 0.0)  # the evader 0.4 m ahead, within `close`
    obs[0, 8:10] = (0.1, 60 / 180)
    assert Surround(config, SurroundConfig(flank=2.0, mate_range=0.1)).act(obs)[0] == pytest.approx(
        0.5
    )


def test_surround_leaves_an_evader_its_share_of_teammates_holds(config):
    """Three pursuers, two live evaders: at most two on one. With both teammates nearer the
    nearest evader, the pursuer takes the other one."""
    obs = blank_obs(config)
    obs[0, 0:3] = (0.2, 0.0, 0.0)  # evader 0: 1 m ahead
    obs[0, 3:6] = (0.4, 0.5, 0.0)  # evader 1: 2 m away, 90° left
    obs[0, 6:8] = (1.0, 0.0)
    obs[0, 8:10] = (0.16, 0.0)  # both teammates 0.8 m ahead, nearer evader 0
    obs[0, 10:12] = (0.17, 0.01)
    quiet = SurroundConfig(flank=0.0, mate_range=0.0)
    assert Surround(config, quiet).act(obs)[0] == pytest.approx(1.0)  # full left turn
    obs[0, 10:12] = (0.4, -0.5)  # one teammate leaves: evader 0 is free again
    assert Surround(config, quiet).act(obs)[0] == pytest.approx(0.5)


def test_policies_are_batched_and_in_range(config):
    env = BatchedPursuit(config, 32)
    obs = env.reset(seeds=np.arange(32)).reshape(-1, config.obs_dim)
    for name in policy_names():
        actions = make_policy(name, config).act(obs)
        assert actions.shape == (96,) and np.all((actions >= 0) & (actions <= 1))
    with pytest.raises(ValueError, match="expects observations"):
        Greedy(config).act(obs[:, :10])
    with pytest.raises(ValueError, match="unknown policy"):
        make_policy("d3qn", config)


def test_policies_read_only_the_observation(config):
    """Same observation, same action, whatever the hidden state behind it."""
    obs = blank_obs(config, 2)
    obs[:, 0:3] = (0.3, 0.2, -0.4)
    for name in ("greedy", "vicsek", "apf-a-5", "surround-1"):
        actions = make_policy(name, config).act(obs)
        assert actions[0] == actions[1]
    assert math.isfinite(float(actions[0]))
