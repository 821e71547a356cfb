"""Surround: divide the evaders among the pursuers, then close in on one's own from a side no
teammate covers (docs/contract.md §3).

A hand-written pursuer of a kind neither evaluation pool holds (Greedy and VICSEK chase the
evader itself; APF-A and D3QN-G weigh potential fields; the PPO agents are learned): it
targets the nearest evader that fewer than its share of teammates are nearer to (three
pursuers, two evaders: at most two on one), and steers toward it with a sideways term that
pushes its angle around the evader away from the teammates near the same evader, fading to a
straight approach within `close` metres. Soft repulsion from the nearest obstacle point and
from near teammates, as a sum of directions; only the direction is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.geometry import wrap
from hola_ray.policies import _ego
from hola_ray.policies.base import Policy


@dataclass(frozen=True)
class SurroundConfig:
    """Parameters of the surrounding pursuer."""

    flank: float = 1.0
    """weight of the sideways term against the unit term toward the evader"""
    spread: float = 2.0 * math.pi / 3.0
    """teammates nearer than this angle (around the evader) to one's own angle push it away"""
    close: float = 0.5
    """metres from the evader within which the sideways term fades to nothing"""
    obstacle_range: float = 0.35
    """walls and obstacles nearer than this repel"""
    obstacle_gain: float = 3.0
    """strength of the obstacle repulsion at contact"""
    mate_range: float = 0.45
    """teammates nearer than this repel"""
    mate_gain: float = 2.0
    """strength of the teammate repulsion at contact"""


SURROUND_MEMBERS = {
    "surround-1": SurroundConfig(),
    "surround-2": SurroundConfig(flank=1.5, close=0.8, spread=math.pi),
    "surround-3": SurroundConfig(flank=0.3),
}
"""The named settings the registry and the `surround` validation set play (module doc)."""


class Surround(Policy):
    """Divide the evaders, approach one's own from an uncovered side (module doc)."""

    name = "Surround"

    def __init__(self, config: PursuitConfig, params: SurroundConfig | None = None) -> None:
        super().__init__(config)
        self.params = params or SurroundConfig()

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        lay, cfg, p = self.layout, self.config, self.params
        return _surround(
            obs,
            lay.n_evaders,
            lay.obstacle,
            lay.teammates,
            lay.n_pursuers - 1,
            cfg.n_pursuers,
            cfg.obs_distance_scale,
            cfg.unobserved_distance,
            cfg.max_turn,
            p.flank,
            p.spread,
            p.close,
            p.obstacle_range,
            p.obstacle_gain,
            p.mate_range,
            p.mate_gain,
        )


@njit(cache=True)
def _target(obs, n, n_e, k_mates, n_mates, team, scale, far):
    """The evader row n takes: the nearest live one that fewer than its share of teammates
    are nearer to (the nearest live one if every evader is taken); −1 when none is live.
    The share is the team's `team` pursuers over the live evaders, rounded up."""
    live = 0
    for e in range(n_e):
        if obs[n, 3 * e] < far:
            live += 1
    if live == 0:
        return -1
    share = (team + live - 1) // live
    best, best_d, best_taken = -1, 1e9, True
    for e in range(n_e):
        if obs[n, 3 * e] >= far:
            continue
        ex, ey, d = _ego.point(obs, n, 3 * e, scale)
        nearer = 0
        for j in range(n_mates):
            k = k_mates + 2 * j
            if obs[n, k] >= far:
                continue
            tx, ty, _ = _ego.point(obs, n, k, scale)
            if math.hypot(tx - ex, ty - ey) < d:
                nearer += 1
        taken = nearer >= share
        if (best_taken and not taken) or (taken == best_taken and d < best_d):
            best, best_d, best_taken = e, d, taken
    return best


@njit(cache=True)
def _surround(
    obs, n_e, k_obst, k_mates, n_mates, team, scale, far, max_turn,
    flank, spread, close, obst_range, obst_gain, mate_range, mate_gain,
):  # fmt: skip
    out = np.empty(obs.shape[0])
    for n in range(obs.shape[0]):
        fx, fy = 0.0, 0.0
        e = _target(obs, n, n_e, k_mates, n_mates, team, scale, far)
        if e >= 0:
            ex, ey, d = _ego.point(obs, n, 3 * e, scale)
            d = max(d, 1e-6)
            fx, fy = ex / d, ey / d
            own = math.atan2(-ey, -ex)  # one's own angle around the evader
            push = 0.0
            for j in range(n_mates):
                k = k_mates + 2 * j
                if obs[n, k] >= far:
                    continue
                tx, ty, _ = _ego.point(obs, n, k, scale)
                if math.hypot(tx - ex, ty - ey) > d + close:
                    continue  # a teammate far behind: not near this evader
                gap = wrap(own - math.atan2(ty - ey, tx - ex))
                if abs(gap) < spread:
                    push += math.copysign((spread - abs(gap)) / spread, gap)
            w = flank * min(max((d - close) / close, 0.0), 1.0) * push
            # one's angle around the evader grows along (ey, −ex)/d
            fx += w * ey / d
            fy -= w * ex / d
        fx, fy = _ego.repel(
            fx, fy, obs, n, k_obst, k_mates, n_mates, scale, far,
            obst_range, obst_gain, mate_range, mate_gain,
        )  # fmt: skip
        out[n] = _ego.to_action(fx, fy, max_turn)
    return out
