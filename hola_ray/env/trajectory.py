"""One episode's true state step by step, as `hola_ray.evaluation.trajectory.record` plays
it and `hola_ray.env.render` draws it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


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

    @property
    def steps(self) -> int:
        return int(self.pursuer_pos.shape[0] - 1)
