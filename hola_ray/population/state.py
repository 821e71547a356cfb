"""The population and its HyFoG, with the coordinator's decisions: pure Python, no Ray.

Nodes get increasing integer ids: the pre-trained members 0..K−1, then one id per
generation's learner candidate. Each member sits in a population slot (0..max_size−1),
which is the Oracle's frozen partner module `member_<slot>`; a replaced member's slot
goes to the newcomer. The HyFoG has room for the population plus the candidate.

How partners are drawn from the members and whether a candidate joins is the method's
(`hola_ray.population.rules.Rules`, implemented in `hola_ray.methods`): this class holds
only what every method shares.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from hola_ray.hypergraph import HyFoG, centrality, lowest_centrality, rank_of


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
    """Members, their slots and the HyFoG over them."""

    def __init__(
        self,
        l: int,  # noqa: E741 - the paper's l
        max_size: int,
        top_m: int,
        preferred_only: bool = False,
        sizes: Sequence[int] | None = None,
    ):
        self.l, self.max_size, self.top_m = l, max_size, top_m
        self.sizes = tuple(sorted(set(sizes))) if sizes is not None else (l,)
        """the teams' sizes, so the hyperedges' (contract §6.2): (l,) for the paper's team"""
        self.preferred_only = preferred_only
        """a candidate joins only at η > 0 (`PopulationConfig.preferred_only`)"""
        self.learner_returns: dict[int, float] = {}
        """member → mean team return of the latest candidate's hyperedges that hold it (with
        teams of several sizes, each return less its size's mean)"""
        self.extra: dict[str, Any] = {}
        """what a method keeps between generations (JSON-safe; PBT: its agents' scores
        and hyperparameters)"""
        self.hyfog = HyFoG(l=l, max_size=max_size + 1, sizes=self.sizes)
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
        """Every l-set of members, or every set of each size, smallest first: the
        hyperedges of G_0."""
        return [tuple(c) for k in self.sizes for c in itertools.combinations(self.members, k)]

    def thin(self, count: int, rng: np.random.Generator) -> list[tuple[int, ...]]:
        """Keep `count` of the members' hyperedges (all when `count` is 0 or at least their
        number), drawn by `rng` among the draws that leave every member in one at least;
        returns the node sets removed. A complete G_0 is regular, and on a regular
        hypergraph φ from the Myerson value is φ from the mean reward: a thinned one is not."""
        edges = [e.nodes for e in self.hyfog.edges if set(e.nodes) <= set(self.members)]
        if not 0 < count < len(edges):
            return []
        for _ in range(10_000):
            keep = set(rng.choice(len(edges), size=count, replace=False).tolist())
            if {v for k in keep for v in edges[k]} == set(self.members):
                gone = [edges[k] for k in range(len(edges)) if k not in keep]
                for nodes in gone:
                    self.hyfog.remove_edge(nodes)
                return gone
        raise ValueError(f"no {count} of the {len(edges)} hyperedges hold every member")

    def candidate_edges(self, count: int, rng: np.random.Generator) -> list[tuple[int, ...]]:
        """The candidate with `count` distinct (l − 1)-sets of members (all when count is 0
        or at least their number), in a fixed order; with several sizes, `count` sets of
        each size k, of k − 1 members, smallest first."""
        if self.candidate is None:
            raise ValueError("no candidate proposed")
        out = []
        for k in self.sizes:
            sets = list(itertools.combinations(self.members, k - 1))
            if 0 < count < len(sets):
                picks = np.sort(rng.choice(len(sets), size=count, replace=False))
                sets = [sets[j] for j in picks]
            out += [(self.candidate, *rest) for rest in sets]
        return out

    def record(self, results: Iterable[EdgeResult]) -> None:
        """Write measured hyperedge weights into the HyFoG."""
        results = list(results)
        for r in results:
            self.hyfog.set_weight(r.nodes, r.team_return, r.episodes)
        if self.candidate is not None:
            with_candidate = [r for r in results if self.candidate in r.nodes]
            # teams of several sizes (contract §6): each return as its difference from the
            # mean of its size's, as a team's return is not neutral to its size
            by_size: dict[int, list[float]] = {}
            for r in with_candidate:
                by_size.setdefault(len(r.nodes), []).append(r.team_return)
            offset = {k: float(np.mean(v)) if len(by_size) > 1 else 0.0 for k, v in by_size.items()}
            for member in self.members:
                returns = [
                    r.team_return - offset[len(r.nodes)]
                    for r in with_candidate
                    if member in r.nodes
                ]
                if returns:
                    self.learner_returns[member] = float(np.mean(returns))

    def decide(self, admit: bool = True) -> Decision:
        """Accept the candidate if `admit` and its η rank is within the top m (and, where
        `preferred_only`, its η is above 0); seat it, replacing the lowest-η member when
        full; otherwise remove it with its hyperedges (a best-response method never admits:
        the candidate is measured and turned away)."""
        node = self.candidate
        if node is None:
            raise ValueError("no candidate to decide on")
        rank = rank_of(self.hyfog, node)
        eta = centrality(self.hyfog)[node]
        replaced = slot = None
        accepted = admit and rank <= self.top_m and (eta > 0 or not self.preferred_only)
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

    # ---- views --------------------------------------------------------------------------
    def member_graph(self) -> HyFoG:
        """The HyFoG restricted to members (the candidate and its hyperedges left out)."""
        if self.candidate is None:
            return self.hyfog
        g = HyFoG.from_dict(self.hyfog.to_dict())
        g.remove_node(self.candidate)
        return g

    def drawable(self, exclude_slot: int | None = None) -> list[int]:
        """Members a partner may be drawn from: every one but the member in `exclude_slot`
        (PBT: an agent trains with the others)."""
        return [v for v in self.members if self.slots[v] != exclude_slot]

    def slot_member(self, slot: int) -> int:
        """The member sitting in `slot`."""
        return next(v for v, s in self.slots.items() if s == slot)

    def eta(self) -> dict[int, float]:
        return centrality(self.member_graph())

    # ---- persistence --------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        if self.candidate is not None:
            raise ValueError("persist between generations only (a candidate is undecided)")
        return {
            "l": self.l,
            **({} if self.sizes == (self.l,) else {"sizes": list(self.sizes)}),
            "max_size": self.max_size,
            "top_m": self.top_m,
            "preferred_only": self.preferred_only,
            "learner_returns": {str(k): v for k, v in self.learner_returns.items()},
            "extra": self.extra,
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
            data.get("preferred_only", False),
            data.get("sizes"),
        )
        p.learner_returns = {int(k): v for k, v in data.get("learner_returns", {}).items()}
        p.extra = dict(data.get("extra", {}))
        for key in ("agent_scores", "agent_hyper"):  # a run saved before `extra` (PBT's)
            if data.get(key):
                p.extra[key] = data[key]
        p.hyfog = HyFoG.from_dict(data["hyfog"])
        p.slots = {int(k): int(v) for k, v in data["slots"].items()}
        p.next_node = int(data["next_node"])
        return p


def edge_seed(run_seed: int, generation: int, nodes: Sequence[int]) -> int:
    """The evaluation seed of a hyperedge: fixed by run, generation and node set, never by
    which worker plays it or when."""
    key = [run_seed, generation, *sorted(nodes)]
    return int(np.random.SeedSequence(key).generate_state(1, dtype=np.uint64)[0])
