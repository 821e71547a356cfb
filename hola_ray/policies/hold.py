"""A seat that holds its heading: the floor of the learner's scale (docs/contract.md §5).

It never turns (action 0.5: a heading change of 0), so it flies straight from its spawn
until it hits something. What a team scores with it in one seat is what the other seats
achieve without help: at 3 vs 2 with the HeT pool about half the episodes."""

from __future__ import annotations

import numpy as np

from hola_ray.policies.base import Policy


class HoldHeading(Policy):
    """Action 0.5 in every row: no turn."""

    name = "hold"

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        return np.full(obs.shape[0], 0.5)
