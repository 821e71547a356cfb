"""The population and its HyFoG, with the coordinator's decisions: pure Python, no Ray.

Nodes get increasing integer ids: the pre-trained members 0..K−1, then one id per
generation's learner candidate. Each member sits in a population slot (0..max_size−1),
which is the Oracle's frozen partner module `member_<slot>`; a replaced member's slot
goes to the newcomer. The HyFoG has room for the population plus the candidate.

How the Oracle draws partners (`phi_kind`, the method's): the shifted inverse of a node
value (myerson, mean_reward; `hola_ray.hypergraph.phi`), uniform, or MEP's rank rule over
the learner's returns with each member (rank). A population that does not `join` stays
fixed: every candidate is measured and then turned away (best-response methods).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from hola_ray.hypergraph import HyFoG, centrality, lowest_centrality, phi, rank_of
from hola_ray.hypergraph.phi import node_values


@dataclass(frozen=True)
class EdgeResult:
    """The Grapher's measurement of one hyperedge."""

    nodes: tuple[int, ...]
    team_return: float
    """mean over episodes of the team's summed return: the hyperedge weight"""
    success: float
    collision: float
    length: float
    episodes: int


@dataclass(frozen=True)
class Decision:
    """The coordinator's verdict on a generation's candidate."""

    candidate: int
    accepted: bool
    rank: int
    """competition rank of the candidate's η (1 = best)"""
    eta: float
    replaced: int | None
    """the lowest-η member that made room, if the population was full"""
    slot: int | None
    """the candidate's population slot when accepted"""
    copied_from: int | None = None
    """pbt: the member whose weights the candidate took (exploit), if it did"""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class Population:
    """Members, their slots, the HyFoG over them, and the φ/η views of it."""

    def __init__(  # noqa: PLR0913
        self,
        l: int,  # noqa: E741
        max_size: int,
        top_m: int,
        phi_kind: str,
        phi_shift: float,
        joins: bool = True,
        rank_beta: float = 3.0,
    ):
        self.l, self.max_size, self.top_m = l, max_size, top_m
        self.phi_kind, self.phi_shift = phi_kind, phi_shift
        self.joins, self.rank_beta = joins, rank_beta
        self.learner_returns: dict[int, float] = {}
        """member → mean team return of the latest candidate's hyperedges that hold it"""
        self.agent_scores: dict[int, float] = {}
        """pbt: slot → mean team return of its agent's hyperedges after its last training"""
        self.agent_hyper: dict[int, dict[str, float]] = {}
        """pbt: slot → its agent's PPO hyperparameters (lr, entropy_coef)"""
        self.hyfog = HyFoG(l=l, max_size=max_size + 1)
        self.slots: dict[int, int] = {}  # member node → population slot
        self.next_node = 0
        self.candidate: int | None = None

    # ---- membership ---------------------------------------------------------------------
    @property
    def members(self) -> list[int]:
        """Member nodes in insertion order (the candidate is not a member)."""
        return [v for v in self.hyfog.nodes if v in self.slots]

    def add_initial(self, count: int) -> list[int]:
        """Seat `count` pre-trained members in slots 0..count−1."""
        if self.slots:
            raise ValueError("the initial population is already seated")
        if not self.l <= count <= self.max_size:
            raise ValueError(f"initial population must hold {self.l}..{self.max_size} members")
        nodes = list(range(count))
        for node in nodes:
            self.hyfog.add_node(node)
            self.slots[node] = node
        self.next_node = count
        return nodes

    def propose(self) -> int:
        """Add the generation's learner snapshot as a candidate node; returns its id."""
        if self.candidate is not None:
            raise ValueError(f"candidate {self.candidate} is still undecided")
        node = self.next_node
        self.next_node += 1
        self.hyfog.add_node(node)
        self.candidate = node
        return node

    def initial_edges(self) -> list[tuple[int, ...]]:
        """Every l-set of members: the hyperedges of G_0."""
        return [tuple(c) for c in itertools.combinations(self.members, self.l)]

    def candidate_edges(self, count: int, rng: np.random.Generator) -> list[tuple[int, ...]]:
        """The candidate with `count` distinct (l − 1)-sets of members (all when count is 0
        or at least their number), in a fixed order."""
        if self.candidate is None:
            raise ValueError("no candidate proposed")
        sets = list(itertools.combinations(self.members, self.l - 1))
        if 0 < count < len(sets):
            picks = np.sort(rng.choice(len(sets), size=count, replace=False))
            sets = [sets[k] for k in picks]
        return [(self.candidate, *rest) for rest in sets]

    def record(self, results: Iterable[EdgeResult]) -> None:
        """Write measured hyperedge weights into the HyFoG."""
        results = list(results)
        for r in results:
            self.hyfog.set_weight(r.nodes, r.team_return, r.episodes)
        if self.candidate is not None:
            with_candidate = [r for r in results if self.candidate in r.nodes]
            for member in self.members:
                returns = [r.team_return for r in with_candidate if member in r.nodes]
                if returns:
                    self.learner_returns[member] = float(np.mean(returns))

    def decide(self) -> Decision:
        """Accept the candidate if its η rank is within the top m; seat it, replacing the
        lowest-η member when full; otherwise remove it with its hyperedges."""
        node = self.candidate
        if node is None:
            raise ValueError("no candidate to decide on")
        rank = rank_of(self.hyfog, node)
        eta = centrality(self.hyfog)[node]
        replaced = slot = None
        accepted = self.joins and rank <= self.top_m
        if accepted:
            if len(self.slots) >= self.max_size:
                replaced = lowest_centrality(self.hyfog, exclude=node)
                slot = self.slots.pop(replaced)
                self.hyfog.remove_node(replaced)
            else:
                slot = min(set(range(self.max_size)) - set(self.slots.values()))
            self.slots[node] = slot
            self.learner_returns.pop(replaced, None)
        else:
            self.hyfog.remove_node(node)
        self.candidate = None
        return Decision(node, accepted, rank, eta, replaced, slot)

    def pbt_step(
        self,
        slot: int,
        rng: np.random.Generator,
        quantile: float = 0.25,
        perturb: Sequence[float] = (0.8, 1.2),
    ) -> Decision:
        """PBT (Jaderberg 2017, as Carroll 2019 use it): the candidate, the agent of `slot`
        after its training, replaces its parent there; its score is the mean return of its
        hyperedges. Once every agent has a score, an agent in the bottom `quantile`
        exploits (takes the weights and score of an agent drawn from the top `quantile`,
        `copied_from`) and explores (its lr and entropy coefficient are that agent's times
        a factor drawn from `perturb`); a copied candidate's hyperedges are dropped, as they
        measured the weights it no longer has."""
        node = self.candidate
        if node is None:
            raise ValueError("no candidate to decide on")
        parent = next(v for v, s in self.slots.items() if s == slot)
        edges = [w for nodes, w in self.hyfog.weights() if node in nodes]
        rank = rank_of(self.hyfog, node)
        eta = centrality(self.hyfog)[node]
        self.slots.pop(parent)
        self.hyfog.remove_node(parent)
        self.slots[node] = slot
        self.agent_scores[slot] = float(np.mean(edges)) if edges else float("-inf")
        copied = None
        if len(self.agent_scores) == len(self.slots):
            k = max(1, int(len(self.slots) * quantile))
            order = sorted(self.agent_scores, key=lambda s: self.agent_scores[s])
            if slot in order[:k] and slot not in order[-k:]:
                source = int(rng.choice(order[-k:]))
                copied = next(v for v, s in self.slots.items() if s == source)
                self.agent_scores[slot] = self.agent_scores[source]
                self.agent_hyper[slot] = {
                    h: v * float(rng.choice(perturb)) for h, v in self.agent_hyper[source].items()
                }
                self.hyfog.remove_node(node)
                self.hyfog.add_node(node)
        self.candidate = None
        return Decision(node, True, rank, eta, parent, slot, copied)

    # ---- views --------------------------------------------------------------------------
    def member_graph(self) -> HyFoG:
        """The HyFoG restricted to members (the candidate and its hyperedges left out)."""
        if self.candidate is None:
            return self.hyfog
        g = HyFoG.from_dict(self.hyfog.to_dict())
        g.remove_node(self.candidate)
        return g

    def phi(self, exclude_slot: int | None = None) -> dict[int, float]:
        """Partner distribution over members (see the module doc); `exclude_slot`: every
        member but that slot's (PBT: an agent trains with the others)."""
        members = [v for v in self.members if self.slots[v] != exclude_slot]
        if self.phi_kind == "uniform":
            return {v: 1.0 / len(members) for v in members}
        if self.phi_kind == "rank":
            return rank_priorities(
                {v: self.learner_returns.get(v) for v in members}, self.rank_beta
            )
        full = phi(self.member_graph(), self.phi_kind, self.phi_shift)
        kept = {v: full[v] for v in members}
        norm = sum(kept.values())
        return {v: w / norm for v, w in kept.items()}

    def eta(self) -> dict[int, float]:
        return centrality(self.member_graph())

    def values(self) -> dict[int, float | None]:
        """The node values φ is drawn by: the Myerson value or mean hyperedge reward, the
        learner's return with each member (rank), none (uniform)."""
        if self.phi_kind == "uniform":
            return dict.fromkeys(self.members)
        if self.phi_kind == "rank":
            return {v: self.learner_returns.get(v) for v in self.members}
        return node_values(self.member_graph(), self.phi_kind)

    # ---- persistence --------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        if self.candidate is not None:
            raise ValueError("persist between generations only (a candidate is undecided)")
        return {
            "l": self.l,
            "max_size": self.max_size,
            "top_m": self.top_m,
            "phi_kind": self.phi_kind,
            "phi_shift": self.phi_shift,
            "joins": self.joins,
            "rank_beta": self.rank_beta,
            "learner_returns": {str(k): v for k, v in self.learner_returns.items()},
            "agent_scores": {str(k): v for k, v in self.agent_scores.items()},
            "agent_hyper": {str(k): v for k, v in self.agent_hyper.items()},
            "next_node": self.next_node,
            "slots": {str(k): v for k, v in self.slots.items()},
            "hyfog": self.hyfog.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Population:
        p = cls(
            data["l"],
            data["max_size"],
            data["top_m"],
            data["phi_kind"],
            data["phi_shift"],
            joins=data.get("joins", True),
            rank_beta=data.get("rank_beta", 3.0),
        )
        p.learner_returns = {int(k): v for k, v in data.get("learner_returns", {}).items()}
        p.agent_scores = {int(k): v for k, v in data.get("agent_scores", {}).items()}
        p.agent_hyper = {int(k): dict(v) for k, v in data.get("agent_hyper", {}).items()}
        p.hyfog = HyFoG.from_dict(data["hyfog"])
        p.slots = {int(k): int(v) for k, v in data["slots"].items()}
        p.next_node = int(data["next_node"])
        return p


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


def edge_seed(run_seed: int, generation: int, nodes: Sequence[int]) -> int:
    """The evaluation seed of a hyperedge: fixed by run, generation and node set, never by
    which worker plays it or when."""
    key = [run_seed, generation, *sorted(nodes)]
    return int(np.random.SeedSequence(key).generate_state(1, dtype=np.uint64)[0])
