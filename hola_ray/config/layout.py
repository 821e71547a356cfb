"""Where each reading sits in a pursuer's observation vector (contract §1): the one layout the
simulator writes, `PursuitConfig.obs_dim` and the observation space read, the policies, the
ONNX manifest and the scenario adapters slice by, and an export's input size is read back
with (`evaders_for`). Built from a config as `PursuitConfig.layout`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ObsLayout:
    """Offsets into one pursuer's observation.

    `[evaders: n_e × (distance, bearing, relative heading)]`
    `[nearest obstacle: (distance, bearing)]`
    `[other pursuers: (n_p − 1) × (distance, bearing)]`
    `[own: x, y, cos θ, sin θ]`
    `[other pursuers' headings: (n_p − 1) × relative heading]` (only with
    `observe_headings`)

    Distances are divided by `obs_distance_scale`, angles by π and are relative to the
    observer's heading (positive = to its left).
    """

    n_pursuers: int
    """pursuers in the scenario"""
    n_evaders: int
    """evaders in the scenario"""
    headings: bool = False
    """the other pursuers' headings follow the own block (`PursuitConfig.observe_headings`)"""
    far: float = 1.0
    """the largest normalised distance an observation holds (the arena's diagonal or the
    unobserved distance, whichever is larger, over `obs_distance_scale`)"""

    @classmethod
    def evaders_for(cls, inputs: int, n_pursuers: int, headings: bool = False) -> int | None:
        """The number of evaders an observation of `inputs` entries holds with `n_pursuers`
        pursuers; None when no number fits."""
        rest = cls(n_pursuers, 0, headings).dim
        if inputs <= rest or (inputs - rest) % 3:
            return None
        return (inputs - rest) // 3

    @property
    def evaders(self) -> int:
        """Offset of the first evader triple."""
        return 0

    @property
    def obstacle(self) -> int:
        """Offset of the nearest-obstacle pair."""
        return 3 * self.n_evaders

    @property
    def teammates(self) -> int:
        """Offset of the first teammate pair."""
        return self.obstacle + 2

    @property
    def own(self) -> int:
        """Offset of (x, y, cos θ, sin θ)."""
        return self.teammates + 2 * (self.n_pursuers - 1)

    @property
    def proximity(self) -> list[int]:
        """Offsets of the distances a pursuer must keep from collision: the nearest obstacle
        point, then each teammate."""
        return [self.obstacle] + [self.teammates + 2 * j for j in range(self.n_pursuers - 1)]

    @property
    def base_dim(self) -> int:
        """Length of the observation without the teammates' headings: what a policy trained
        without them reads (the observation's first entries); with `headings`, the offset
        of the first teammate heading."""
        return self.own + 4

    @property
    def dim(self) -> int:
        """Length of the observation."""
        return self.base_dim + (self.n_pursuers - 1 if self.headings else 0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Elementwise (low, high) of the observation, for its `Box` space."""
        far = self.far
        low = np.zeros(self.dim, dtype=np.float32)
        high = np.zeros(self.dim, dtype=np.float32)
        for e in range(self.n_evaders):
            i = self.evaders + 3 * e
            low[i : i + 3] = (0.0, -1.0, -1.0)
            high[i : i + 3] = (far, 1.0, 1.0)
        low[self.obstacle : self.obstacle + 2] = (0.0, -1.0)
        high[self.obstacle : self.obstacle + 2] = (far, 1.0)
        for j in range(self.n_pursuers - 1):
            i = self.teammates + 2 * j
            low[i : i + 2] = (0.0, -1.0)
            high[i : i + 2] = (far, 1.0)
        low[self.own : self.own + 4] = (0.0, 0.0, -1.0, -1.0)
        high[self.own : self.own + 4] = (1.0, 1.0, 1.0, 1.0)
        low[self.base_dim :] = -1.0
        high[self.base_dim :] = 1.0
        return low, high
