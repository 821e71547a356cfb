"""MEP (Zhao et al. 2023): a best response to the MEP population, its partners drawn by
MEP's prioritised sampling, p ∝ rank(1/R)^β over the learner's returns R with each member.
The population is HOLA-Drone's generation 0 and stays fixed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from hola_ray.methods.base import Method, Origin
from hola_ray.population.state import Decision, Population

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig


@dataclass(frozen=True)
class RankPriority:
    """Rules: partners by `rank_priorities` of the learner's latest returns with each
    member (`population.rank_beta`); the learner never joins."""

    beta: float

    def setup(self, population: Population) -> None:
        pass

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        members = population.drawable(exclude_slot)
        return rank_priorities({v: population.learner_returns.get(v) for v in members}, self.beta)

    def values(self, population: Population) -> dict[int, float | None]:
        return {v: population.learner_returns.get(v) for v in population.members}

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        return population.decide(admit=False)


class MEP(Method):
    joins: ClassVar[bool] = False
    origin: ClassVar[Origin] = Origin(shared=True)

    def rules(self, config: RunConfig) -> RankPriority:
        return RankPriority(config.population.rank_beta)


def rank_priorities(returns: dict[int, float | None], beta: float) -> dict[int, float]:
    """MEP's prioritised sampling (Zhao et al. 2023), p ∝ rank(1/R)^β: the members ranked
    by the learner's return R with them, rank 1 for the highest, n for the lowest (the
    order of 1/R when returns are positive, and defined for any sign); tied returns share
    their mean rank; a member without a return yet ranks n. No returns at all: uniform."""
    members = list(returns)
    if not members:
        return {}
    known = {v: r for v, r in returns.items() if r is not None}
    if not known:
        return {v: 1.0 / len(members) for v in members}
    low = min(known.values())
    # unmeasured members tie with (just below) the lowest: they rank last
    x = np.array([known.get(v, low - 1.0) for v in members], dtype=np.float64)
    order = np.argsort(-x, kind="stable")
    ranks = np.empty(len(x))
    ranks[order] = np.arange(1, len(x) + 1)
    for value in np.unique(x):  # ties share their mean rank
        tied = x == value
        ranks[tied] = ranks[tied].mean()
    weights = ranks**beta
    weights /= weights.sum()
    return dict(zip(members, weights.tolist(), strict=True))


METHOD = MEP("mep", "MEP: a best response to the MEP population, prioritised by rank(1/return)^β")
