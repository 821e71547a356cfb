"""VICSEK: group chasing after Janosov et al. (2017) (docs/contract.md §3).

Desired velocity = a chase term toward the evader's predicted position (corrected by the
relative velocity) + soft repulsion from the nearest wall or obstacle + repulsion from
teammates nearer than a set distance. Only its direction is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.geometry import norm
from hola_ray.policies import _ego
from hola_ray.policies.base import Policy


@dataclass(frozen=True)
class VicsekConfig:
    """Parameters of the group-chasing pursuer.

    Defaults were picked by a grid search (prediction time × obstacle range and gain ×
    chaser range and gain, 48 points, 300 one-evader episodes on run seed 100, held out
    from the Table II seeds): the best success rate, then fewest collisions.
    """

    prediction_time: float = 2.0
    """most seconds ahead the evader's position is predicted"""
    obstacle_range: float = 0.35
    """walls and obstacles nearer than this repel"""
    obstacle_gain: float = 4.0
    """strength of the obstacle repulsion at contact, relative to the unit chase term"""
    chaser_range: float = 0.9
    """teammates nearer than this repel"""
    chaser_gain: float = 2.0
    """strength of the teammate repulsion at contact, relative to the chase term"""


class Vicsek(Policy):
    """Predictive chase with soft obstacle and chaser repulsion."""

    name = "VICSEK"

    def __init__(self, config: PursuitConfig, params: VicsekConfig | None = None) -> None:
        super().__init__(config)
        self.params = params or VicsekConfig()

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        lay, cfg, p = self.layout, self.config, self.params
        return _vicsek(
            obs,
            lay.n_evaders,
            lay.obstacle,
            lay.teammates,
            lay.n_pursuers - 1,
            cfg.obs_distance_scale,
            cfg.unobserved_distance,
            cfg.max_turn,
            cfg.pursuer_speed,
            cfg.evader_speed,
            p.prediction_time,
            p.obstacle_range,
            p.obstacle_gain,
            p.chaser_range,
            p.chaser_gain,
        )


@njit(cache=True)
def _vicsek(
    obs,
    n_e,
    k_obst,
    k_mates,
    n_mates,
    scale,
    far,
    max_turn,
    v_p,
    v_e,
    t_pred,
    obst_range,
    obst_gain,
    chaser_range,
    chaser_gain,
):
    out = np.empty(obs.shape[0])
    for n in range(obs.shape[0]):
        e = _ego.nearest_live_evader(obs, n, n_e, far)
        fx, fy = 0.0, 0.0
        if e >= 0:
            ex, ey, ed = _ego.point(obs, n, 3 * e, scale)
            he = obs[n, 3 * e + 2] * math.pi
            # relative velocity of the evader seen from the pursuer (own heading is +x)
            rvx = v_e * math.cos(he) - v_p
            rvy = v_e * math.sin(he)
            tau = min(ed / (v_p + v_e), t_pred)
            cx = ex + tau * rvx
            cy = ey + tau * rvy
            cn = norm(cx, cy)
            if cn > 0.0:
                fx, fy = cx / cn, cy / cn
        fx, fy = _ego.repel(
            fx, fy, obs, n, k_obst, k_mates, n_mates, scale, far,
            obst_range, obst_gain, chaser_range, chaser_gain,
        )  # fmt: skip
        out[n] = _ego.to_action(fx, fy, max_turn)
    return out
