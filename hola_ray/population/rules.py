"""What a method decides about its population, as the coordinator asks it.

The coordinator owns the `Population` and does the bookkeeping every method shares; a
method's `Rules` (implemented in `hola_ray.methods`, handed to the coordinator when the run
starts) say how partners are drawn from the members and who joins. Rules objects are plain,
picklable values: they travel to the coordinator actor.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from hola_ray.population.state import Decision, Population


class Rules(Protocol):
    def setup(self, population: Population) -> None:
        """Called once the initial members are seated (generation 0)."""

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        """The partner distribution over members (member node → probability), without the
        member in `exclude_slot` when one is given."""

    def values(self, population: Population) -> dict[int, float | None]:
        """The node values φ is drawn by (None where the method has none), for `status`."""

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        """The verdict on the generation's candidate (`slot`: the agent it was trained
        from, for a method that trains its members in turn)."""
