"""The horizon truncates: RLlib's bookkeeping marks every agent of an episode whose agents
are all done terminated; `horizon_is_truncation` leaves the pursuers alive at the horizon
truncated only (so PPO and the DQN bootstrap there) and a pursuer that collided terminated."""

from __future__ import annotations

import dataclasses

import numpy as np
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.horizon import horizon_is_truncation
from hola_ray.env.pettingzoo_env import PursuitEnv


def straight_episode(config: PursuitConfig, seed: int) -> MultiAgentEpisode:
    """Every pursuer flies straight on (action 0.5), recorded as RLlib's env runner does."""
    env = PursuitEnv(config)
    obs, infos = env.reset(seed=seed)
    episode = MultiAgentEpisode()
    episode.add_env_reset(observations=obs, infos=infos)
    while env.agents:
        act = {a: np.array([0.5], np.float32) for a in env.agents}
        obs, rewards, terms, truncs, infos = env.step(act)
        terms["__all__"] = all(terms.values())
        truncs["__all__"] = all(truncs.values())
        episode.add_env_step(obs, act, rewards, infos, terminateds=terms, truncateds=truncs)
    return episode


def test_pursuers_alive_at_the_horizon_are_truncated_and_a_crashed_one_terminated():
    # 30 steps: a pursuer spawned below a bar hits it within 25 (0.03 m a step), the others
    # fly on; find such an episode among the first seeds
    config = dataclasses.replace(PursuitConfig(n_evaders=1), horizon=30)
    for seed in range(50):
        episode = straight_episode(config, seed)
        crashed = {a for a, sa in episode.agent_episodes.items() if len(sa) < 30}
        if crashed and len(crashed) < len(episode.agent_episodes):
            break
    else:
        raise AssertionError("no episode with a crash and a survivor in 50 seeds")
    # RLlib's bookkeeping: the episode and every agent terminated, at the horizon too
    assert episode.is_truncated and episode.is_terminated
    assert all(sa.is_terminated for sa in episode.agent_episodes.values())
    horizon_is_truncation(episode)
    assert episode.is_truncated and not episode.is_terminated
    for agent, sa in episode.agent_episodes.items():
        if agent in crashed:
            assert sa.is_terminated and not sa.is_truncated, agent
        else:
            assert sa.is_truncated and not sa.is_terminated, agent


def test_an_episode_that_ended_before_the_horizon_is_left_terminated():
    config = dataclasses.replace(PursuitConfig(n_evaders=1), horizon=1000)
    episode = straight_episode(config, seed=3)  # flying straight, every pursuer crashes
    assert episode.is_terminated and not episode.is_truncated
    horizon_is_truncation(episode)
    assert episode.is_terminated
    assert all(sa.is_terminated for sa in episode.agent_episodes.values())


def test_the_dqn_and_the_pettingzoo_path_apply_it():
    from hola_ray.oracle.d3qn_train import (
        D3QNRun,
        D3QNSettings,
        HorizonTruncates,
        algorithm_config,
    )
    from hola_ray.oracle.trainer import _RepushOnRecreate

    run = D3QNRun(seed=0, env=PursuitConfig(n_evaders=1), d3qn=D3QNSettings())
    assert algorithm_config(run).callbacks_class is HorizonTruncates
    assert "on_episode_end" in vars(_RepushOnRecreate) and "on_episode_end" in vars(
        HorizonTruncates
    )
