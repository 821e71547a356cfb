"""HOLA-Drone (paper §IV) and its two controls: the learner trains with partners drawn by
φ, the shifted inverse of a node value of the HyFoG, and joins the population when its η
rank is within the top m.

- `hola`: φ from the Myerson value of the hypergraphic game (docs/contract.md §4);
- `hola_r`: φ from each member's mean hyperedge reward (HOLA-Drone_R);
- `uniform`: partners drawn uniformly, the control for what φ adds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from hola_ray.methods.base import Method, Origin
from hola_ray.population.rules import InverseValue, Uniform

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig


class HolaDrone(Method):
    """An MEP population grown open-endedly; partners drawn by φ of `kind` (or uniformly)."""

    origin: ClassVar[Origin] = Origin(shared=True)

    def __init__(self, name: str, kind: str, description: str):
        super().__init__(name, description)
        self.kind = kind
        """myerson, mean_reward, or uniform"""

    def rules(self, config: RunConfig) -> InverseValue | Uniform:
        if self.kind == "uniform":
            return Uniform()
        return InverseValue(self.kind, config.population.phi_shift)

    def rival(self, config: RunConfig) -> InverseValue:
        """hola's φ is compared with hola_r's, hola_r's and uniform's with hola's: where
        the two are the same draw (a regular hypergraph), the methods are one."""
        kind = "mean_reward" if self.kind == "myerson" else "myerson"
        return InverseValue(kind, config.population.phi_shift)


HOLA = HolaDrone("hola", "myerson", "HOLA-Drone: partners drawn by the inverse Myerson value")
HOLA_R = HolaDrone("hola_r", "mean_reward", "HOLA-Drone_R: partners by the inverse mean reward")
UNIFORM = HolaDrone(
    "uniform", "uniform", "HOLA-Drone with uniform partners: the control for what φ adds"
)
