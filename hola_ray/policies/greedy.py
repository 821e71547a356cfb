"""Greedy: chase the nearest live evader; sidestep anything within reach (docs/contract.md §3)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from hola_ray.config.scenario import PursuitConfig
from hola_ray.policies import _ego
from hola_ray.policies.base import Policy


@dataclass(frozen=True)
class GreedyConfig:
    """Parameters of the Greedy pursuer."""

    avoid_distance: float = 0.3
    """an obstacle or teammate nearer than this makes the pursuer turn away"""
    avoid_turn: float = math.radians(20)
    """how far it turns away, radians"""


class Greedy(Policy):
    """Turn toward the nearest live evader; when an obstacle or teammate is within
    `avoid_distance`, turn `avoid_turn` away from the nearest such thing instead."""

    name = "Greedy"

    def __init__(self, config: PursuitConfig, params: GreedyConfig | None = None) -> None:
        super().__init__(config)
        self.params = params or GreedyConfig()

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        lay = self.layout
        return _greedy(
            obs,
            lay.n_evaders,
            lay.obstacle,
            lay.teammates,
            lay.n_pursuers - 1,
            self.config.obs_distance_scale,
            self.config.unobserved_distance,
            self.config.max_turn,
            self.params.avoid_distance,
            self.params.avoid_turn,
        )


@njit(cache=True)
def _greedy(obs, n_e, k_obst, k_mates, n_mates, scale, far, max_turn, avoid, avoid_turn):
    out = np.empty(obs.shape[0])
    for n in range(obs.shape[0]):
        e = _ego.nearest_live_evader(obs, n, n_e, far)
        turn = obs[n, 3 * e + 1] * math.pi if e >= 0 else 0.0
        near_d = avoid
        near_b = 0.0
        hit = False
        if obs[n, k_obst] * scale < near_d:
            near_d = obs[n, k_obst] * scale
            near_b = obs[n, k_obst + 1]
            hit = True
        for j in range(n_mates):
            k = k_mates + 2 * j
            if obs[n, k] < far and obs[n, k] * scale < near_d:
                near_d = obs[n, k] * scale
                near_b = obs[n, k + 1]
                hit = True
        if hit:
            turn = -avoid_turn if near_b >= 0.0 else avoid_turn
        out[n] = _ego.turn_action(turn, max_turn)
    return out
