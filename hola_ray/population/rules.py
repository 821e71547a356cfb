"""What a method decides about its population, as the coordinator asks it.

The coordinator owns the `Population` and does the bookkeeping every method shares; a
method's `Rules` (one of the kinds below, chosen and parameterised by the method in
`hola_ray.methods` and handed to the coordinator when the run starts) say how partners are
drawn from the members and who joins. Rules objects are plain, picklable values: they
travel to the coordinator actor, which unpickles them without importing the methods (and
with them torch and RLlib: 2 core-seconds of every coordinator's start).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hola_ray.hypergraph import centrality, phi, rank_of
from hola_ray.hypergraph.phi import node_values
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


@dataclass(frozen=True)
class Uniform:
    """Rules: partners drawn uniformly from the members; a candidate joins when `admit`
    and its η rank is within the top m."""

    admit: bool = True

    def setup(self, population: Population) -> None:
        pass

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        members = population.drawable(exclude_slot)
        return {v: 1.0 / len(members) for v in members}

    def values(self, population: Population) -> dict[int, float | None]:
        return dict.fromkeys(population.members)

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        return population.decide(admit=self.admit)


@dataclass(frozen=True)
class InverseValue:
    """Rules: φ = the normalised shifted inverse of a node value (`kind`: myerson or
    mean_reward; `hola_ray.hypergraph.phi`) over the members a partner may be drawn from;
    a candidate joins when its η rank is within the top m."""

    kind: str
    shift: float

    def setup(self, population: Population) -> None:
        pass

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        full = phi(population.member_graph(), self.kind, self.shift)
        kept = {v: full[v] for v in population.drawable(exclude_slot)}
        norm = sum(kept.values())
        return {v: w / norm for v, w in kept.items()}

    def values(self, population: Population) -> dict[int, float | None]:
        return node_values(population.member_graph(), self.kind)

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        return population.decide()


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


@dataclass(frozen=True)
class ExploitExplore:
    """Rules: partners uniform over the other agents; the candidate (the agent of `slot`
    after its training) replaces its parent there, then exploits and explores.

    Kept in `population.extra`: `agent_scores` (slot → the mean team return of its agent's
    hyperedges after its last training) and `agent_hyper` (slot → its lr and entropy
    coefficient), keyed by the slot as a string."""

    quantile: float
    perturb: Sequence[float]
    lr: float
    entropy_coef: float

    def setup(self, population: Population) -> None:
        """Every agent at the run's lr and entropy coefficient, no scores yet; a population
        that holds them already (a resumed run) keeps its own."""
        if "agent_hyper" in population.extra:
            return
        population.extra["agent_scores"] = {}
        population.extra["agent_hyper"] = {
            str(slot): {"lr": self.lr, "entropy_coef": self.entropy_coef}
            for slot in population.slots.values()
        }

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        return Uniform().phi(population, exclude_slot)

    def values(self, population: Population) -> dict[int, float | None]:
        return Uniform().values(population)

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        """The candidate replaces its parent in `slot`; its score is the mean return of its
        hyperedges. Once every agent has a score, an agent in the bottom quantile takes the
        weights and score of one drawn from the top quantile (`copied_from`) and that
        agent's hyperparameters times a factor drawn from `perturb`; a copied candidate's
        hyperedges are dropped, as they measured weights it no longer has."""
        p, node = population, population.candidate
        if node is None or slot is None:
            raise ValueError("no candidate to decide on, or no slot it was trained from")
        scores: dict[str, float] = p.extra["agent_scores"]
        hyper: dict[str, dict[str, float]] = p.extra["agent_hyper"]
        parent = p.slot_member(slot)
        edges = [w for nodes, w in p.hyfog.weights() if node in nodes]
        rank = rank_of(p.hyfog, node)
        eta = centrality(p.hyfog)[node]
        p.slots.pop(parent)
        p.hyfog.remove_node(parent)
        p.slots[node] = slot
        scores[str(slot)] = float(np.mean(edges)) if edges else float("-inf")
        copied = None
        if len(scores) == len(p.slots):
            k = max(1, int(len(p.slots) * self.quantile))
            order = sorted(scores, key=lambda s: scores[s])
            if str(slot) in order[:k] and str(slot) not in order[-k:]:
                source = int(rng.choice(order[-k:]))
                copied = p.slot_member(source)
                scores[str(slot)] = scores[str(source)]
                hyper[str(slot)] = {
                    h: v * float(rng.choice(self.perturb)) for h, v in hyper[str(source)].items()
                }
                p.hyfog.remove_node(node)
                p.hyfog.add_node(node)
        p.candidate = None
        return Decision(node, True, rank, eta, parent, slot, copied)
