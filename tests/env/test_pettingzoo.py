"""PettingZoo's own contract tests, and the batched core against single environments."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test, seed_test
from pettingzoo.utils.conversions import parallel_to_aec

from hola_ray.env import BatchedPursuit, PursuitConfig
from hola_ray.env.pettingzoo_env import PursuitEnv
from hola_ray.policies import Vicsek


def test_parallel_api_test():
    parallel_api_test(PursuitEnv(), num_cycles=1000)


def test_parallel_api_test_other_team_sizes():
    parallel_api_test(PursuitEnv(PursuitConfig(n_pursuers=5, n_evaders=1)), num_cycles=300)
    parallel_api_test(PursuitEnv(PursuitConfig(n_pursuers=1, n_evaders=3)), num_cycles=300)


def test_parallel_seed_test():
    parallel_seed_test(PursuitEnv)


def test_seed_test_on_aec_wrapper():
    seed_test(lambda: parallel_to_aec(PursuitEnv()), num_cycles=100)


def test_spaces_follow_the_config():
    env = PursuitEnv(PursuitConfig(n_pursuers=4, n_evaders=3))
    assert env.possible_agents == ["pursuer_0", "pursuer_1", "pursuer_2", "pursuer_3"]
    # 3 evaders × 3 + obstacle 2 + 3 teammates × 2 + own 4 = 21
    assert env.observation_space("pursuer_0").shape == (21,)
    obs, _ = env.reset(seed=0)
    assert all(env.observation_space(a).contains(o) for a, o in obs.items())


def test_reset_options_fix_the_state():
    env = PursuitEnv()
    state = {
        "pursuer_pos": np.array([[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]]),
        "evader_heading": np.array([0.0, 1.0]),
    }
    env.reset(seed=3, options=state)
    np.testing.assert_array_equal(env.core.pursuer_pos[0], state["pursuer_pos"])
    np.testing.assert_array_equal(env.core.evader_heading[0], state["evader_heading"])
    with pytest.warns(UserWarning, match="unknown reset option"):
        env.reset(options={"evader_speed": 1.0})
    with pytest.raises(ValueError, match="inside the arena"):
        env.reset(options={"pursuer_pos": np.array([[-0.1, 0.5], [1.5, 0.5], [2.5, 0.5]])})


def test_infos_carry_metrics_at_the_end():
    env = PursuitEnv(dataclasses.replace(PursuitConfig(), horizon=30))
    env.reset(seed=1)
    infos = {}
    while env.agents:
        live = list(env.agents)
        _, _, _, _, infos = env.step({a: np.array([0.5], dtype=np.float32) for a in live})
    assert infos and all(set(info) >= {"success", "collision", "length"} for info in infos.values())


def _drive(k: int, seeds: list[int], actions_for, config: PursuitConfig | None = None) -> None:
    """Step a batch of k and k single envs with the same actions; compare every output."""
    config = config or PursuitConfig()
    batch = BatchedPursuit(config, k)
    batch_obs = batch.reset(seeds=seeds).copy()
    singles = [PursuitEnv(config) for _ in range(k)]
    single_obs = [env.reset(seed=s)[0] for env, s in zip(singles, seeds, strict=True)]
    for b, env in enumerate(singles):
        for i, agent in enumerate(env.agents):
            np.testing.assert_array_equal(single_obs[b][agent], batch_obs[b, i])
    for t in range(config.horizon):
        actions = actions_for(t, batch.obs)
        running = ~batch.done
        result = batch.step(actions)
        for b, env in enumerate(singles):
            if not running[b]:
                assert not env.agents
                continue
            live = list(env.agents)
            obs, rew, term, trunc, _ = env.step({a: actions[b, env._index[a]] for a in live})
            for agent in live:
                i = env._index[agent]
                assert rew[agent] == result.reward[b, i], (t, b, agent)
                assert term[agent] == bool(result.terminated[b] or result.disabled[b, i])
                assert trunc[agent] == bool(result.truncated[b])
            for agent in env.agents:
                np.testing.assert_array_equal(obs[agent], result.obs[b, env._index[agent]])
            np.testing.assert_array_equal(env.core.pursuer_pos[0], batch.pursuer_pos[b])
            np.testing.assert_array_equal(env.core.evader_pos[0], batch.evader_pos[b])
        if batch.done.all():
            break
    assert batch.done.all()


def test_batched_core_equals_single_envs_random_actions():
    rng = np.random.default_rng(7)
    _drive(6, [0, 1, 2, 3, 4, 99], lambda t, obs: rng.random((6, 3)))


def test_batched_core_equals_single_envs_under_a_policy():
    policy = Vicsek(PursuitConfig())
    _drive(5, [10, 11, 12, 13, 14], lambda t, obs: policy.act(obs.reshape(-1, 16)).reshape(5, 3))


def test_independent_resets_leave_other_episodes_alone():
    config = PursuitConfig()
    env = BatchedPursuit(config, 2)
    env.reset(seeds=[1, 2])
    reference = BatchedPursuit(config, 1)
    reference.reset(seeds=[2])
    for _ in range(20):
        env.step(np.full((2, 3), 0.6))
        reference.step(np.full((1, 3), 0.6))
    env.reset(mask=np.array([True, False]), seeds=[5])
    assert env.t.tolist() == [0, 20]
    for _ in range(20):
        env.step(np.full((2, 3), 0.6))
        reference.step(np.full((1, 3), 0.6))
    np.testing.assert_array_equal(env.evader_pos[1], reference.evader_pos[0])
    np.testing.assert_array_equal(env.obs[1], reference.obs[0])


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (float("nan"), "action of pursuer_1 is nan: it must be a finite number"),
        (None, "action of pursuer_1 is None"),
        ("fast", "action of pursuer_1 is not a number: 'fast'"),
        ([0.1, 0.2], r"action of pursuer_1 must hold one number"),
    ],
)
def test_a_bad_action_is_named_by_its_agent(action, message):
    env = PursuitEnv(PursuitConfig())
    env.reset(seed=0)
    actions = {a: np.array([0.5], np.float32) for a in env.agents}
    actions["pursuer_1"] = action
    with pytest.raises(ValueError, match=message):
        env.step(actions)


def test_an_unknown_or_finished_agent_key_is_refused():
    env = PursuitEnv(PursuitConfig())
    env.reset(seed=0)
    actions = {a: np.array([0.5], np.float32) for a in env.agents}
    with pytest.raises(ValueError, match=r"unknown agent\(s\) \['pursuer_7'\]"):
        env.step(actions | {"pursuer_7": np.array([0.5])})
    env.agents.remove("pursuer_2")  # as if disabled
    with pytest.raises(ValueError, match=r"action for \['pursuer_2'\], no longer in the episode"):
        env.step(actions)
