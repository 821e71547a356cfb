"""MEP (Zhao et al. 2023): a best response to the MEP population, its partners drawn by
MEP's prioritised sampling, p ∝ rank(1/R)^β over the learner's returns R with each member.
The population is HOLA-Drone's generation 0 and stays fixed."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from hola_ray.methods.base import Method, Origin
from hola_ray.population.rules import RankPriority

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig


class MEP(Method):
    origin: ClassVar[Origin] = Origin(shared=True)

    def may_join(self) -> bool:
        return False

    def rules(self, config: RunConfig) -> RankPriority:
        return RankPriority(config.population.rank_beta)


METHOD = MEP("mep", "MEP: a best response to the MEP population, prioritised by rank(1/return)^β")
