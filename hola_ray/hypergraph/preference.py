"""Preference hypergraph, hyper-preference centrality and the approximate oracle's test."""

from __future__ import annotations

from hola_ray.hypergraph.hyfog import HyFoG, Hyperedge, NodeId


def preference_hypergraph(g: HyFoG) -> dict[NodeId, tuple[Hyperedge, ...]]:
    """Each node's out-hyperedges: its best incident hyperedge by weight, one of each size
    the node has hyperedges of (one in the paper's HyFoG, whose teams are all of l).

    Teams of several sizes (contract §6) are compared within a size only: the weight is the
    team's summed return, and neither it nor its share per member is neutral to the size
    (the summed return grows with the team; per member, a larger team pays more teammate
    penalties and crashes for the same capture bonus), so across sizes either rule would
    make one size every node's best. Ties are broken deterministically: among hyperedges of
    equal weight the one with more episodes behind it wins, then the one whose members, in
    insertion order, come first (lexicographic on their insertion ranks). A node with no
    hyperedge has no out-edge.
    """
    best: dict[NodeId, dict[int, Hyperedge]] = {}
    for edge in g.edges:  # sorted by insertion ranks, so the first of equals is kept
        size = len(edge.nodes)
        for node in edge.nodes:
            held = best.setdefault(node, {}).get(size)
            if held is None or (edge.weight, edge.episodes) > (held.weight, held.episodes):
                best[node][size] = edge
    return {v: tuple(by_size[k] for k in sorted(by_size)) for v, by_size in best.items()}


def in_degree(g: HyFoG) -> dict[NodeId, int]:
    """d(i): how many out-hyperedges of other nodes contain i (summed over the sizes)."""
    degree = dict.fromkeys(g.nodes, 0)
    for source, edges in preference_hypergraph(g).items():
        for edge in edges:
            for node in edge.nodes:
                if node != source:
                    degree[node] += 1
    return degree


def centrality(g: HyFoG) -> dict[NodeId, float]:
    """Hyper-preference centrality η_i = d(i) / (|V| − 1) (0 for a lone node); with teams of
    several sizes, d(i) sums a vote per size and η divides by their number too, so each
    size's preferences weigh alike and η stays in [0, 1]."""
    n = len(g)
    votes = (n - 1) * len(g.sizes)
    return {v: (d / votes if n > 1 else 0.0) for v, d in in_degree(g).items()}


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
