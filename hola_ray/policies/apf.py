"""APF-A: the artificial potential field of DACOOP-A (Zhang et al., RA-L 2023) (contract §3).

Read from the public code, Zero8319/DACOOP-A, `Codes/APF_function_for_DQN.py` (forces in
millimetres) and `Codes/environment.py` (`from_action_to_APF`, the action → (λ, η) grid):

- attraction: the unit vector to the target (`attract`);
- obstacle repulsion, within the influence range 800 mm of the nearest obstacle point
  (`APF_decision`): η·(1/(d − 100) − 1/800)/(d − 100)² along the away-vector (`repulse`);
- inter-pursuer force: the mean over teammates within perception range of
  (0.5 − λ/(d − 200)) along the vector to the teammate (`individual`; without DACOOP-A's
  learned attention weights, which belong to its DQN, not to the field);
- wall following, when (attraction + repulsion)·attraction < 0: the repulsion turned by
  ±90°, the one nearer the own heading while the inter-pursuer force is below 1, else the
  one along it; plus the repulsion itself within 150 mm of the obstacle (`wall_follow`);
- the resultant force's direction is the heading the pursuer turns to.

Units: with d in metres, d_mm = 1000·d, so η·(1/(d_mm − 100) − 1/800)/(d_mm − 100)² =
η·10⁻⁹·(1/(d − 0.1) − 1/0.8)/(d − 0.1)² and λ/(d_mm − 200) = (λ/1000)/(d − 0.2): η in mm³
becomes η·10⁻⁹ m³ and λ in mm becomes λ/1000 m. The grid (`from_action_to_APF`): action
index a → η = (1e6, 1e7, 1e8)[a // 8] mm³ and λ = (a mod 8)·4000/7 mm, so here
η ∈ {0.001, 0.01, 0.1} m³ and λ = k·4/7 m, k = 0…7. The arena's own turn limit applies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.geometry import norm
from hola_ray.policies import _ego
from hola_ray.policies.base import Policy


@dataclass(frozen=True)
class APFConfig:
    """The APF-A force field and its (λ, η) grid."""

    lambdas: tuple[float, ...] = tuple(k * 4.0 / 7.0 for k in range(8))
    """inter-pursuer balance λ candidates, metres (DACOOP-A: k·4000/7 mm)"""
    etas: tuple[float, ...] = (1e-3, 1e-2, 1e-1)
    """obstacle repulsion scale η candidates, m³ (DACOOP-A: 1e6, 1e7, 1e8 mm³)"""
    influence_range: float = 0.8
    """obstacles farther than this do not repel"""
    repulsion_offset: float = 0.1
    """subtracted from the obstacle distance (the drone safe radius)"""
    pair_offset: float = 0.2
    """subtracted from teammate distances in the inter-pursuer force (κ)"""
    wall_follow_push: float = 0.15
    """while wall following this close to the obstacle, the repulsion is added too"""

    @property
    def pairs(self) -> list[tuple[float, float]]:
        """Every (λ, η), indexed as DACOOP's action: index = 8·η_index + λ_index."""
        return [(lam, eta) for eta in self.etas for lam in self.lambdas]


class APFA(Policy):
    """APF-A with one fixed (λ, η) pair, chasing the nearest live evader."""

    def __init__(
        self, config: PursuitConfig, pair: int = 0, params: APFConfig | None = None
    ) -> None:
        super().__init__(config)
        self.params = params or APFConfig()
        pairs = self.params.pairs
        if not 0 <= pair < len(pairs):
            raise ValueError(f"pair must be in [0, {len(pairs) - 1}], got {pair}")
        self.pair = pair
        self.lam, self.eta = pairs[pair]
        self.name = f"APF-A(λ={self.lam:g}, η={self.eta:g})"

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        n = obs.shape[0]
        return apf_actions(
            self.config,
            self.params,
            obs,
            np.full(n, self.lam),
            np.full(n, self.eta),
            np.full(n, -1, dtype=np.int64),
        )


def apf_actions(
    config: PursuitConfig,
    params: APFConfig,
    obs: np.ndarray,
    lam: np.ndarray,
    eta: np.ndarray,
    target: np.ndarray,
) -> np.ndarray:
    """APF-A actions for rows with their own λ [N], η [N] and target evader [N] (−1: nearest)."""
    lay = config.layout
    return _apf(
        obs,
        lam,
        eta,
        target,
        lay.n_evaders,
        lay.obstacle,
        lay.teammates,
        lay.n_pursuers - 1,
        config.obs_distance_scale,
        config.unobserved_distance,
        config.max_turn,
        params.influence_range,
        params.repulsion_offset,
        params.pair_offset,
        params.wall_follow_push,
    )


@njit(cache=True)
def _apf(
    obs,
    lam,
    eta,
    target,
    n_e,
    k_obst,
    k_mates,
    n_mates,
    scale,
    far,
    max_turn,
    reach,
    offset,
    pair_offset,
    push,
):
    out = np.empty(obs.shape[0])
    for n in range(obs.shape[0]):
        e = target[n]
        if e < 0 or obs[n, 3 * e] >= far:
            e = _ego.nearest_live_evader(obs, n, n_e, far)
        if e < 0:
            out[n] = 0.5
            continue
        ex, ey, ed = _ego.point(obs, n, 3 * e, scale)
        ax, ay = (ex / ed, ey / ed) if ed > 0.0 else (0.0, 0.0)

        rx, ry = 0.0, 0.0
        qx, qy, d = _ego.point(obs, n, k_obst, scale)
        if d < reach and d > 0.0:
            s = max(d - offset, 0.005)
            mag = eta[n] * (1.0 / s - 1.0 / reach) / (s * s)
            rx, ry = -mag * qx / d, -mag * qy / d

        ix, iy = 0.0, 0.0
        seen = 0
        for j in range(n_mates):
            k = k_mates + 2 * j
            if obs[n, k] >= far:
                continue
            mx, my, md = _ego.point(obs, n, k, scale)
            if md <= 0.0:
                continue
            w = 0.5 - lam[n] / max(md - pair_offset, 0.01)
            ix += w * mx / md
            iy += w * my / md
            seen += 1
        if seen > 0:
            ix /= seen
            iy /= seen

        fx = ax + rx + ix
        fy = ay + ry + iy
        if (ax + rx) * ax + (ay + ry) * ay < 0.0:
            # wall following along the obstacle tangent (own heading is +x)
            t1x, t1y = -ry, rx
            if norm(ix, iy) < 1.0:
                # the tangent nearer the own heading (+x)
                fx, fy = (t1x, t1y) if t1x >= 0.0 else (-t1x, -t1y)
            else:
                fx, fy = (t1x, t1y) if t1x * ix + t1y * iy > 0.0 else (-t1x, -t1y)
            if d < push:
                fx += rx
                fy += ry
        out[n] = _ego.to_action(fx, fy, max_turn)
    return out
