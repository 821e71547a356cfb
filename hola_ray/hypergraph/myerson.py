"""Myerson values of a HyFoG: closed form, brute force over all orders, and sampling.

The coalition value is v(S) = Σ_{T ⊆ S, T ∈ E} w(T). Written as a sum of unanimity games
v = Σ_T w(T)·u_T with u_T(S) = 1 if T ⊆ S, each u_T gives every member of T the value 1/|T|
(symmetry + efficiency + null player), and the Shapley value is linear, so

    MV_i = Σ_{T ∋ i} w(T) / |T|,

which is Σ_{T ∋ i} w(T) / l when every hyperedge holds l nodes (the paper's fixed team).

A HyFoG is connected, so its Myerson value equals this Shapley value (paper Appendix).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from hola_ray.hypergraph.hyfog import HyFoG, NodeId

EXACT_MAX_NODES = 9
"""Largest |V| the brute-force method accepts (9! = 362,880 orders)."""


def myerson_value(
    g: HyFoG, method: str = "closed", samples: int = 2000, seed: int = 0
) -> dict[NodeId, float]:
    """Node → Myerson value, by `closed` form, `exact` enumeration or `sample`-ing orders."""
    if method == "closed":
        return _closed(g)
    if method == "exact":
        return _exact(g)
    if method == "sample":
        return myerson_sample(g, samples, seed)[0]
    raise ValueError(f"method must be 'closed', 'exact' or 'sample', got {method!r}")


def _closed(g: HyFoG) -> dict[NodeId, float]:
    value = dict.fromkeys(g.nodes, 0.0)
    for nodes, weight in g.weights():
        share = weight / len(nodes)
        for node in nodes:
            value[node] += share
    return value


def coalition_values(g: HyFoG) -> np.ndarray:
    """v(S) for every coalition S as a bitmask over `g.nodes` ([2^|V|] float64)."""
    n = len(g)
    index = {v: k for k, v in enumerate(g.nodes)}
    v = np.zeros(1 << n)
    for nodes, weight in g.weights():
        v[sum(1 << index[node] for node in nodes)] += weight
    for bit in range(n):  # sum over subsets (zeta transform)
        step = 1 << bit
        v = v.reshape(-1, 2 * step)
        v[:, step:] += v[:, :step]
        v = v.reshape(-1)
    return v


def _exact(g: HyFoG) -> dict[NodeId, float]:
    """(1/|V|!) Σ_σ [v(P_i^σ ∪ {i}) − v(P_i^σ)], every order enumerated."""
    n = len(g)
    if n == 0:
        return {}
    if n > EXACT_MAX_NODES:
        raise ValueError(f"exact enumeration is for |V| <= {EXACT_MAX_NODES}, got {n}")
    v = coalition_values(g)
    orders = np.array(list(itertools.permutations(range(n))), dtype=np.int64)  # [n!, n]
    bits = np.left_shift(1, orders)
    after = np.cumsum(bits, axis=1)  # coalition once position k has joined
    before = after - bits
    marginal = v[after] - v[before]  # [n!, n], column k = the k-th joiner's contribution
    total = np.zeros(n)
    np.add.at(total, orders.ravel(), marginal.ravel())
    return {node: float(total[k] / math.factorial(n)) for k, node in enumerate(g.nodes)}


def myerson_sample(
    g: HyFoG, samples: int = 2000, seed: int = 0
) -> tuple[dict[NodeId, float], dict[NodeId, float]]:
    """Permutation-sampling estimate and its standard error, node → (value), node → (se).

    In an order σ, hyperedge T adds w(T) exactly when its last member joins, so node i's
    marginal contribution is the sum of w(T) over the T ∋ i in which i comes last.
    """
    if samples < 2:
        raise ValueError(f"samples must be >= 2, got {samples}")
    n = len(g)
    if n == 0:
        return {}, {}
    index = {v: k for k, v in enumerate(g.nodes)}
    edges = g.edges
    rng = np.random.default_rng(seed)
    position = np.argsort(rng.random((samples, n)), axis=1)  # [K, n]: a random order each row
    marginal = np.zeros((samples, n))
    rows = np.arange(samples)
    for edge in edges:
        members = np.array([index[v] for v in edge.nodes])
        last = members[np.argmax(position[:, members], axis=1)]
        marginal[rows, last] += edge.weight
    mean = marginal.mean(axis=0)
    se = marginal.std(axis=0, ddof=1) / math.sqrt(samples)
    return (
        {node: float(mean[k]) for k, node in enumerate(g.nodes)},
        {node: float(se[k]) for k, node in enumerate(g.nodes)},
    )
