"""A fixed set of pursuer observations on which to watch a policy's spread while it trains."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.base import Policy, seated
from hola_ray.policies.greedy import Greedy


def reference_observations(
    config: PursuitConfig,
    episodes: int = 32,
    every: int = 10,
    seed: int = 12_345,
    team: Sequence[Policy] | None = None,
) -> np.ndarray:
    """Observations [N, obs_dim] of active pursuers, every `every` steps of `episodes`
    episodes played by `team` (one policy per seat; a Greedy team by default): start-of-
    episode states and the chase after them. The same config, team and seed always give
    the same set."""
    env = BatchedPursuit(config, episodes)
    obs = env.reset(seeds=episode_seeds(seed, episodes))
    seats = seated(team) if team is not None else [Greedy(config)] * config.n_pursuers
    for policy in seats:
        policy.reset(np.ones(episodes, dtype=bool))
    actions = np.zeros((episodes, config.n_pursuers))
    out = []
    step = 0
    while not env.done.all():
        if step % every == 0:
            out.append(obs[~env.done][env.pursuer_active[~env.done]].copy())
        for i, policy in enumerate(seats):
            actions[:, i] = policy.act(obs[:, i])
        obs = env.step(actions).obs
        step += 1
    return np.concatenate(out).astype(np.float32)
