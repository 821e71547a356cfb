"""The φ solver: which teammates the Oracle trains with (paper §IV-B, docs/contract.md §4).

φ favours nodes of low value x (poor cooperators), through an inverse on a shifted,
strictly positive value:

    φ_i = (1 / (x_i − x_min + δ)) / Σ_j 1 / (x_j − x_min + δ),   δ = c · (x_max − x_min),

with c = `shift` (default 0.1). The lowest-value node is weighted 1/δ and the highest
1/((1 + c)·range), a ratio of (1 + c)/c = 11. φ is unchanged by adding a constant to every
value or scaling them all by a positive factor, so negative returns need no special case.
All values equal (or a single node) gives the uniform φ.

kind="myerson": x = Myerson value (HOLA-Drone); kind="mean_reward": x = mean weight of the
node's hyperedges (the HOLA-Drone_R ablation); with teams of several sizes (contract §6),
the mean over sizes of the node's mean weight in each, as a team's weight is not neutral
to its size. With hyperedges of the one size l, MV_i = (d_i / l)·(mean weight of i's hyperedges),
d_i the number of i's hyperedges, so the two kinds give the same φ whenever every node has
the same degree, G_0 (every l-set of the initial members) among them (results/NOTEBOOK.md,
"Why `hola_r` trained exactly like `hola`"); with several sizes MV_i = Σ_{T∋i} w(T)/|T|.

A node with no hyperedge yet takes the lowest value among the nodes that have one, so it
is among the most sampled; when no node has a hyperedge, φ is uniform.
"""

from __future__ import annotations

from hola_ray.hypergraph.hyfog import HyFoG, NodeId
from hola_ray.hypergraph.myerson import myerson_value


def node_values(g: HyFoG, kind: str = "myerson") -> dict[NodeId, float | None]:
    """x_i per node (None for a node with no hyperedge)."""
    weights: dict[NodeId, dict[int, list[float]]] = {v: {} for v in g.nodes}
    for nodes, weight in g.weights():
        for node in nodes:
            weights[node].setdefault(len(nodes), []).append(weight)
    if kind == "myerson":
        mv = myerson_value(g, "closed")
        return {v: (mv[v] if weights[v] else None) for v in g.nodes}
    if kind == "mean_reward":  # per size, then over the sizes: neutral to the sizes' mix
        return {
            v: (sum(sum(w) / len(w) for w in by_size.values()) / len(by_size) if by_size else None)
            for v, by_size in weights.items()
        }
    raise ValueError(f"kind must be 'myerson' or 'mean_reward', got {kind!r}")


def inverse_shifted(values: dict[NodeId, float | None], shift: float = 0.1) -> dict[NodeId, float]:
    """The φ transform of the module docstring over node → value (None = no hyperedge)."""
    if shift <= 0:
        raise ValueError(f"shift must be > 0, got {shift}")
    if not values:
        return {}
    known = [x for x in values.values() if x is not None]
    if not known:
        return {v: 1.0 / len(values) for v in values}
    low, high = min(known), max(known)
    x = {v: (low if value is None else value) for v, value in values.items()}
    spread = high - low
    if spread <= 0:
        return {v: 1.0 / len(values) for v in values}
    inverse = {v: 1.0 / (value - low + shift * spread) for v, value in x.items()}
    norm = sum(inverse.values())
    return {v: w / norm for v, w in inverse.items()}


def phi(g: HyFoG, kind: str = "myerson", shift: float = 0.1) -> dict[NodeId, float]:
    """Node → probability of being drawn as the Oracle's teammate."""
    return inverse_shifted(node_values(g, kind), shift)
