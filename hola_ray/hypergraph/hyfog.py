"""The hypergraphic-form game (paper §IV-A): nodes, weighted hyperedges of l nodes, or, for
teams of changing size (contract §6.2), of any of several sizes."""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Hashable, Iterable, Iterator
from dataclasses import dataclass

NodeId = Hashable
"""A population member's id: an int or a str (JSON-safe)."""


class HyFoGError(ValueError):
    """An operation that would make the HyFoG invalid."""


@dataclass(frozen=True)
class Hyperedge:
    """l nodes that co-played, their mean team return, and the episodes behind it."""

    nodes: tuple[NodeId, ...]
    weight: float
    episodes: int


class HyFoG:
    """G = (V, E, w, l): at most `max_size` nodes; every hyperedge holds exactly l nodes, or
    one of `sizes` nodes (teams of several sizes; l is then the largest).

    Node order is insertion order; it breaks ties everywhere (see `preference_hypergraph`).
    A weight set again for the same node set is merged as a running mean over episodes.
    """

    def __init__(
        self,
        l: int = 3,  # noqa: E741 - the paper's l
        max_size: int = 10,
        sizes: Iterable[int] | None = None,
    ) -> None:
        if not isinstance(l, int) or l < 1:
            raise HyFoGError(f"l must be an integer >= 1, got {l!r}")
        if not isinstance(max_size, int) or max_size < l:
            raise HyFoGError(f"max_size must be an integer >= l ({l}), got {max_size!r}")
        sizes = tuple(sorted(set(sizes))) if sizes is not None else (l,)
        if not sizes or sizes[-1] != l or any(not isinstance(k, int) or k < 1 for k in sizes):
            raise HyFoGError(f"sizes must be integers >= 1, the largest l ({l}), got {sizes!r}")
        self.l = l
        self.sizes = sizes
        """the hyperedge sizes it holds: (l,) for the paper's fixed team"""
        self.max_size = max_size
        self._order: dict[NodeId, int] = {}  # node → insertion rank
        self._next = 0
        self._edges: dict[frozenset, tuple[float, int]] = {}

    # ---- nodes --------------------------------------------------------------------------
    @property
    def nodes(self) -> list[NodeId]:
        """Nodes in insertion order."""
        return list(self._order)

    def __len__(self) -> int:
        return len(self._order)

    def __contains__(self, node: NodeId) -> bool:
        return node in self._order

    def add_node(self, node: NodeId) -> None:
        """Add a node; ids must be ints or strs, new, and there must be room."""
        if isinstance(node, bool) or not isinstance(node, int | str):
            raise HyFoGError(f"node ids must be int or str, got {node!r}")
        if node in self._order:
            raise HyFoGError(f"node {node!r} is already in the HyFoG")
        if len(self._order) >= self.max_size:
            raise HyFoGError(
                f"the HyFoG is full (max_size={self.max_size}); "
                f"remove a node before adding {node!r}"
            )
        self._order[node] = self._next
        self._next += 1

    def remove_node(self, node: NodeId) -> None:
        """Remove a node and every hyperedge that holds it."""
        self._check_node(node)
        del self._order[node]
        self._edges = {k: v for k, v in self._edges.items() if node not in k}

    def _check_node(self, node: NodeId) -> None:
        if node not in self._order:
            raise HyFoGError(f"unknown node {node!r}; nodes: {self.nodes}")

    # ---- hyperedges ----------------------------------------------------------------------
    def set_weight(self, nodes: Iterable[NodeId], weight: float, episodes: int = 1) -> None:
        """Record `episodes` episodes of mean team return `weight` for this node set."""
        nodes = tuple(nodes)
        if len(nodes) not in self.sizes:
            held = f"l={self.l}" if self.sizes == (self.l,) else f"one of {list(self.sizes)}"
            raise HyFoGError(f"a hyperedge holds exactly {held} nodes, got {len(nodes)}")
        if len(set(nodes)) != len(nodes):
            raise HyFoGError(f"a hyperedge may not repeat a node, got {nodes}")
        for node in nodes:
            self._check_node(node)
        weight = float(weight)
        if not math.isfinite(weight):
            raise HyFoGError(f"hyperedge weight must be finite, got {weight}")
        if not isinstance(episodes, int) or episodes < 1:
            raise HyFoGError(f"episodes must be an integer >= 1, got {episodes!r}")
        key = frozenset(nodes)
        if key in self._edges:
            old, n = self._edges[key]
            self._edges[key] = ((old * n + weight * episodes) / (n + episodes), n + episodes)
        else:
            self._edges[key] = (weight, episodes)

    def remove_edge(self, nodes: Iterable[NodeId]) -> None:
        """Remove the hyperedge of this node set."""
        key = frozenset(nodes)
        if key not in self._edges:
            raise HyFoGError(f"no hyperedge {sorted(map(str, key))}")
        del self._edges[key]

    def weight(self, nodes: Iterable[NodeId]) -> float:
        """The weight of this node set's hyperedge."""
        key = frozenset(nodes)
        if key not in self._edges:
            raise HyFoGError(f"no hyperedge {sorted(map(str, key))}")
        return self._edges[key][0]

    def sorted_nodes(self, nodes: Iterable[NodeId]) -> tuple[NodeId, ...]:
        """Nodes in insertion order."""
        return tuple(sorted(nodes, key=self._order.__getitem__))

    @property
    def edges(self) -> list[Hyperedge]:
        """Every hyperedge, node sets in insertion order, sorted by insertion order."""
        out = [Hyperedge(self.sorted_nodes(k), w, n) for k, (w, n) in self._edges.items()]
        return sorted(out, key=lambda e: [self._order[v] for v in e.nodes])

    def weights(self) -> Iterator[tuple[frozenset, float]]:
        """(node set, weight) of every hyperedge, unsorted: the fast path for the math."""
        return ((k, w) for k, (w, _) in self._edges.items())

    def incident(self, node: NodeId) -> Iterator[Hyperedge]:
        """Hyperedges that hold `node`."""
        self._check_node(node)
        return (e for e in self.edges if node in e.nodes)

    def missing_edges(self, node: NodeId) -> list[tuple[NodeId, ...]]:
        """Every node set of a hyperedge's size holding `node` that has no weight yet,
        smallest first."""
        others = [v for v in self.nodes if v != node]
        return [
            self.sorted_nodes((node, *rest))
            for k in self.sizes
            for rest in itertools.combinations(others, k - 1)
            if frozenset((node, *rest)) not in self._edges
        ]

    # ---- JSON ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        sizes = {} if self.sizes == (self.l,) else {"sizes": list(self.sizes)}
        return {
            "l": self.l,
            **sizes,
            "max_size": self.max_size,
            "nodes": self.nodes,
            "edges": [
                {"nodes": list(e.nodes), "weight": e.weight, "episodes": e.episodes}
                for e in self.edges
            ],
        }

    def to_json(self) -> str:
        """Lossless JSON (floats are written with repr precision)."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, data: dict) -> HyFoG:
        g = cls(l=data["l"], max_size=data["max_size"], sizes=data.get("sizes"))
        for node in data["nodes"]:
            g.add_node(node)
        for edge in data["edges"]:
            g.set_weight(edge["nodes"], edge["weight"], edge["episodes"])
        return g

    @classmethod
    def from_json(cls, text: str) -> HyFoG:
        return cls.from_dict(json.loads(text))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, HyFoG) and self.to_dict() == other.to_dict()

    def __repr__(self) -> str:
        sizes = "" if self.sizes == (self.l,) else f", sizes={list(self.sizes)}"
        return (
            f"HyFoG(l={self.l}{sizes}, nodes={len(self)}/{self.max_size}, edges={len(self._edges)})"
        )
