"""D3QN-G: its state is read from the observation, its pair is played by APF-A toward the
first evader (Greedy once it is caught), and its export plays RLlib's DQN module's greedy
pair. One Ray session for the module."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from hola_ray.env.config import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.env.layout import ObsLayout
from hola_ray.policies.apf import APFA
from hola_ray.policies.d3qn import D3QNG, PairActor, dacoop_state
from hola_ray.policies.greedy import Greedy

ONE = PursuitConfig(n_evaders=1)
TWO = PursuitConfig(n_evaders=2)


def observations(config: PursuitConfig, steps: int = 40) -> np.ndarray:
    env = BatchedPursuit(config, 16)
    obs = env.reset(seeds=np.arange(16))
    team = Greedy(config)
    out = []
    for _ in range(steps):
        out.append(obs.reshape(-1, config.obs_dim).copy())
        obs = env.step(team.act(obs.reshape(-1, config.obs_dim)).reshape(16, -1)).obs
    return np.concatenate(out)


def test_the_dacoop_state_is_read_from_the_observation():
    lay = ObsLayout.from_config(TWO)
    obs = np.zeros((2, TWO.obs_dim), np.float32)
    obs[:, 0:3] = (0.3, 0.25, 0.1)  # first evader
    obs[:, 3:6] = (0.9, -0.5, 0.0)  # second evader: not in the state
    obs[:, lay.obstacle : lay.obstacle + 2] = (0.05, -0.75)
    obs[0, lay.teammates : lay.own] = (0.2, 0.1, 0.4, -0.3)
    obs[1, lay.teammates : lay.own] = (0.2, 0.1, 2.0, 0.0)  # one teammate unseen
    state = dacoop_state(obs, lay, TWO.unobserved_distance)
    expected = np.array([[0.05, -0.75, 0.3, 0.25, 0, 0.2, 0.1, 0.4, -0.3]] * 2, np.float32)
    expected[1, 4], expected[1, 7:] = 1, (2.0, 0.0)
    np.testing.assert_array_equal(state, expected)


def test_a_pair_is_played_by_apf_a_and_greedy_takes_over_once_the_first_evader_is_caught():
    obs = observations(ONE)
    actor = PairActor(ONE)
    for pair in (2, 13, 21):
        np.testing.assert_array_equal(
            actor.act(obs, np.full(len(obs), pair)), APFA(ONE, pair).act(obs)
        )
    two = observations(TWO)
    caught = two.copy()
    caught[:, 0:3] = (TWO.unobserved_distance, 0.0, 0.0)
    np.testing.assert_array_equal(
        PairActor(TWO).act(caught, np.full(len(caught), 5)), Greedy(TWO).act(caught)
    )


@pytest.fixture(scope="module")
def dqn(ray_session, tmp_path_factory):
    from hola_ray.policies.d3qn_train import D3QNRun, D3QNSettings, algorithm_config

    run = D3QNRun(
        seed=3,
        env=dataclasses.replace(ONE, horizon=60),
        d3qn=D3QNSettings(
            env_steps=300, learning_starts=50, hidden=(16, 8), head_hidden=(8,), envs=2
        ),
    )
    algo = algorithm_config(run).build_algo()
    algo.train()
    yield run, algo
    algo.stop()


def test_the_export_plays_the_dqn_modules_greedy_pair(dqn):
    from hola_ray.policies.d3qn_train import MODULE, export_from_rllib

    run, algo = dqn
    state = algo.learner_group.get_weights([MODULE])[MODULE]
    policy = D3QNG(run.env, export_from_rllib(state, run))
    obs = observations(run.env)
    states = torch.from_numpy(dacoop_state(obs, policy.layout, run.env.unobserved_distance))
    module = algo.learner_group._learner.module[MODULE]
    with torch.no_grad():
        expected = module.compute_q_values({"obs": states})["qf_preds"]
    np.testing.assert_allclose(policy.q(states).numpy(), expected.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(policy.pairs(obs), expected.argmax(dim=-1).numpy())
    actions = policy.act(obs)
    assert actions.shape == (len(obs),) and np.all((actions >= 0) & (actions <= 1))
    with pytest.raises(ValueError, match="reads 9-dim states"):
        D3QNG(dataclasses.replace(ONE, n_pursuers=4), export_from_rllib(state, run))
