"""A ground station's safety filter on the velocity set-points (a control barrier function
for a drone that moves as its set-point says): it keeps each drone's approach to the walls,
the bars, its teammates and the downed drones slow enough to stop short of them.

For each such neighbour at distance d (the nearest point of a wall or bar; a teammate's
centre) along the unit vector n from the drone, the set-point's speed towards it is held to

    v·n ≤ gain · (d − reach − margin)

where reach is the arena's contact distance (the safe radius; κ between two flying
pursuers, whose share of the closing speed is half each). Far from everything the set-point
passes unchanged; closer than reach + margin it pushes away. It acts on the drones' true
positions as often as the ground station sends set-points (every velocity-loop step), so it
changes the flight, never the policy or what the arena judges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hola_ray.config.scenario import PursuitConfig


@dataclass(frozen=True)
class Guard:
    """The filter's two settings; called on a batch of drones it filters their set-points.
    The defaults were chosen on the flight check (docs/flight.md)."""

    margin: float = 0.05
    """m kept beyond the arena's contact distances"""
    gain: float = 2.0
    """1/s: the approach speed allowed per metre of room left"""

    def __post_init__(self) -> None:
        if self.margin < 0 or self.gain <= 0:
            raise ValueError(f"a guard needs margin >= 0 and gain > 0, got {self}")

    def __call__(
        self,
        config: PursuitConfig,
        pos: np.ndarray,
        v_sp: np.ndarray,
        flying: np.ndarray,
    ) -> np.ndarray:
        """The filtered set-points [B, n, 2] for drones at `pos` [B, n, 2] commanded `v_sp`
        [B, n, 2]; `flying` [B, n] the drones still up (the others are obstacles)."""
        v = v_sp.copy()
        for point, reach, share in self._neighbours(config, pos, flying):
            away = point - pos
            d = np.linalg.norm(away, axis=-1)
            applies = flying & np.isfinite(d)
            n = np.where(applies[..., None], away / np.maximum(d, 1e-9)[..., None], 0.0)
            room = np.where(applies, d - reach - self.margin, 0.0)
            excess = np.maximum(np.sum(v * n, axis=-1) - share * self.gain * room, 0.0)
            v -= excess[..., None] * n
        return v

    @staticmethod
    def _neighbours(config: PursuitConfig, pos: np.ndarray, flying: np.ndarray):
        """(nearest point [B, n, 2], contact distance, share of the closing speed) of each
        wall, box, disc and other drone; a point that does not apply is NaN."""
        x, y = pos[..., 0], pos[..., 1]
        safe = config.safe_radius
        for wall in (
            np.stack([np.zeros_like(x), y], axis=-1),
            np.stack([np.full_like(x, config.arena_width), y], axis=-1),
            np.stack([x, np.zeros_like(y)], axis=-1),
            np.stack([x, np.full_like(y, config.arena_height)], axis=-1),
        ):
            yield wall, safe, 1.0
        for cx, cy, w, h in config.obstacles:
            bar = np.stack(
                [np.clip(x, cx - w / 2, cx + w / 2), np.clip(y, cy - h / 2, cy + h / 2)], axis=-1
            )
            yield bar, safe, 1.0
        for cx, cy, r in config.discs:
            off = np.stack([x - cx, y - cy], axis=-1)
            far = np.maximum(np.linalg.norm(off, axis=-1, keepdims=True), 1e-9)
            yield np.array([cx, cy]) + r * off / far, safe, 1.0
        n = pos.shape[1]
        for j in range(1, n):  # the drone j seats along, for every seat at once
            other = np.roll(pos, -j, axis=1)
            up = np.roll(flying, -j, axis=1)
            yield np.where(up[..., None], other, np.nan), config.pursuer_collision_distance, 0.5
            yield np.where(up[..., None], np.nan, other), safe, 1.0
