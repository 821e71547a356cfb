"""One episode's true state step by step, as `hola_ray.evaluation.trajectory.record` plays
it and `hola_ray.env.render` draws it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hola_ray.config.scenario import PursuitConfig


@dataclass(frozen=True)
class Trajectory:
    """States at steps 0..T of one episode, and its events."""

    pursuer_pos: np.ndarray  # [T + 1, n_p, 2]
    pursuer_heading: np.ndarray  # [T + 1, n_p]
    pursuer_active: np.ndarray  # [T + 1, n_p] bool
    evader_pos: np.ndarray  # [T + 1, n_e, 2]
    evader_heading: np.ndarray  # [T + 1, n_e]
    evader_alive: np.ndarray  # [T + 1, n_e] bool
    captures: list[tuple[int, int, tuple[float, float]]]  # (step, evader, where)
    collisions: list[tuple[int, int, tuple[float, float]]]  # (step, pursuer, where)
    metrics: dict[str, Any]
    policy_names: list[str]
    pursuer_present: np.ndarray | None = None  # [T + 1, n_p] bool: in play; None: all
    arena: str | None = None
    """the arena the episode was played in (drawn at its reset where `env.arenas` is set)"""

    def present(self) -> np.ndarray:
        """[T + 1, n_p] bool: each pursuer in play at each step (a team that changes: not
        before it joins nor after it lands)."""
        if self.pursuer_present is None:
            return np.ones(self.pursuer_active.shape, dtype=bool)
        return self.pursuer_present

    def scenario(self, config: PursuitConfig) -> PursuitConfig:
        """`config` as this episode was played: in its own arena where arenas are drawn."""
        if config.arenas and self.arena is not None:
            return config.in_arena(self.arena)
        return config

    @property
    def steps(self) -> int:
        return int(self.pursuer_pos.shape[0] - 1)
