"""APF-A: the DACOOP artificial potential field with attention (SPEC §3).

Force = unit attraction to the target evader + obstacle repulsion scaled by η + the mean
inter-pursuer force scaled by λ; when attraction and repulsion oppose, the pursuer follows
the obstacle's tangent. The 24 (λ, η) pairs are 8 λ × 3 η, converted from DACOOP's
millimetre units to metres (λ: 30 mm → 0.03 m; η: 1.5e8 mm³ → 0.15 m³).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from hola_ray.env.config import PursuitConfig
from hola_ray.env.geometry import norm
from hola_ray.env.layout import ObsLayout
from hola_ray.policies import _ego
from hola_ray.policies.base import Policy


@dataclass(frozen=True)
class APFConfig:
    """The APF-A force field and its (λ, η) grid."""

    lambdas: tuple[float, ...] = (0.03, 0.1, 0.25, 0.5, 0.75, 1.0, 2.0, 3.0)
    """inter-pursuer balance λ candidates, metres"""
    etas: tuple[float, ...] = (0.0, 0.15, 0.3)
    """obstacle repulsion scale η candidates"""
    influence_range: float = 0.8
    """obstacles farther than this do not repel"""
    repulsion_offset: float = 0.1
    """subtracted from the obstacle distance (the drone safe radius)"""
    pair_offset: float = 0.2
    """subtracted from teammate distances in the inter-pursuer force (κ)"""

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
    lay = ObsLayout.from_config(config)
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
        out[n] = _ego.to_action(fx, fy, max_turn)
    return out
