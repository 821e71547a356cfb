"""Preference hypergraph, hyper-preference centrality and the approximate oracle's test."""

from __future__ import annotations

from hola_ray.hypergraph.hyfog import HyFoG, Hyperedge, NodeId


def preference_hypergraph(g: HyFoG) -> dict[NodeId, Hyperedge]:
    """Each node's out-hyperedge: its best incident hyperedge by weight per member.

    The weight is the team's summed return, which grows with the team: hyperedges of
    several sizes (contract §6) are compared by weight per member, w(T)/|T|, else the
    largest teams would be every node's best; those of one size by weight, as the paper
    has it. Ties are broken deterministically: among equals the one with more episodes
    behind it wins, then the one whose members, in insertion order, come first
    (lexicographic on their insertion ranks). A node with no hyperedge has no out-edge.
    """
    best: dict[NodeId, Hyperedge] = {}
    for edge in g.edges:  # sorted by insertion ranks, so the first of equals is kept
        for node in edge.nodes:
            held = best.get(node)
            if held is None or _better(edge, held):
                best[node] = edge
    return best


def _better(edge: Hyperedge, held: Hyperedge) -> bool:
    """`edge` beats `held`: more weight per member (cross-multiplied: exact for one size),
    then more episodes."""
    mine = edge.weight * len(held.nodes)
    theirs = held.weight * len(edge.nodes)
    if len(edge.nodes) == len(held.nodes):
        mine, theirs = edge.weight, held.weight
    return (mine, edge.episodes) > (theirs, held.episodes)


def in_degree(g: HyFoG) -> dict[NodeId, int]:
    """d(i): how many other nodes' out-hyperedges contain i."""
    degree = dict.fromkeys(g.nodes, 0)
    for source, edge in preference_hypergraph(g).items():
        for node in edge.nodes:
            if node != source:
                degree[node] += 1
    return degree


def centrality(g: HyFoG) -> dict[NodeId, float]:
    """Hyper-preference centrality η_i = d(i) / (|V| − 1) (0 for a lone node)."""
    n = len(g)
    return {v: (d / (n - 1) if n > 1 else 0.0) for v, d in in_degree(g).items()}


def ranking(g: HyFoG) -> list[NodeId]:
    """Nodes by centrality, highest first; equal η keeps insertion order."""
    eta = centrality(g)
    return sorted(g.nodes, key=lambda v: -eta[v])  # sorted is stable


def rank_of(g: HyFoG, node: NodeId) -> int:
    """Competition rank of `node` by η: 1 + the number of nodes with strictly higher η."""
    eta = centrality(g)
    if node not in eta:
        raise KeyError(f"unknown node {node!r}")
    return 1 + sum(1 for v in eta if eta[v] > eta[node])


def within_top(g: HyFoG, node: NodeId, m: int) -> bool:
    """The approximate oracle's acceptance test: `node`'s η rank is within the top m."""
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    return rank_of(g, node) <= m


def lowest_centrality(g: HyFoG, exclude: NodeId | None = None) -> NodeId:
    """The node to replace when the population is full: lowest η, earliest inserted first."""
    eta = centrality(g)
    candidates = [v for v in g.nodes if v != exclude]
    if not candidates:
        raise ValueError("no node to choose from")
    return min(candidates, key=lambda v: eta[v])
