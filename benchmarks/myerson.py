"""Myerson value: closed form against brute force over all |V|! orders, measured in one run.

- |V| = 8, l = 3, all 56 hyperedges: brute force (8! = 40,320 orders) vs closed form.
- Closed form at |V| = 10 (all 120 hyperedges) and at |V| = 1000 with 10,000 hyperedges.
The last line is one JSON object.

    python benchmarks/myerson.py
"""

from __future__ import annotations

import itertools
import json
import time

import numpy as np

from hola_ray.hypergraph import HyFoG, myerson_value


def complete_game(n: int, l: int, seed: int) -> HyFoG:  # noqa: E741
    rng = np.random.default_rng(seed)
    g = HyFoG(l=l, max_size=n)
    for v in range(n):
        g.add_node(v)
    for nodes in itertools.combinations(range(n), l):
        g.set_weight(nodes, float(rng.normal(50, 20)))
    return g


def sparse_game(n: int, l: int, edges: int, seed: int) -> HyFoG:  # noqa: E741
    rng = np.random.default_rng(seed)
    g = HyFoG(l=l, max_size=n)
    for v in range(n):
        g.add_node(v)
    seen: set[frozenset] = set()
    while len(seen) < edges:
        nodes = frozenset(rng.choice(n, size=l, replace=False).tolist())
        if nodes not in seen:
            seen.add(nodes)
            g.set_weight(tuple(nodes), float(rng.normal(50, 20)))
    return g


def best_ms(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best * 1e3


def main() -> None:
    g8 = complete_game(8, 3, seed=0)
    exact_ms = best_ms(lambda: myerson_value(g8, "exact"), 3)
    closed_ms_8 = best_ms(lambda: myerson_value(g8, "closed"), 50)
    exact, closed = myerson_value(g8, "exact"), myerson_value(g8, "closed")
    max_diff = max(abs(exact[v] - closed[v]) for v in g8.nodes)
    g10 = complete_game(10, 3, seed=1)
    closed_ms_10 = best_ms(lambda: myerson_value(g10, "closed"), 50)
    g1000 = sparse_game(1000, 3, 10_000, seed=2)
    closed_ms_big = best_ms(lambda: myerson_value(g1000, "closed"), 5)

    print(
        f"|V|=8, l=3, 56 edges: brute force {exact_ms:9.2f} ms   closed {closed_ms_8:7.3f} ms   "
        f"ratio {exact_ms / closed_ms_8:,.0f}×   max |diff| {max_diff:.1e}"
    )
    print(f"|V|=10, l=3, 120 edges: closed {closed_ms_10:.3f} ms")
    print(f"|V|=1000, l=3, 10,000 edges: closed {closed_ms_big:.2f} ms")
    print(
        json.dumps(
            {
                "exact_ms_v8": round(exact_ms, 3),
                "closed_ms_v8": round(closed_ms_8, 4),
                "exact_over_closed_ratio_v8": round(exact_ms / closed_ms_8, 1),
                "max_abs_diff_v8": max_diff,
                "closed_ms_v10": round(closed_ms_10, 4),
                "closed_ms_10000_edges": round(closed_ms_big, 3),
            }
        )
    )


if __name__ == "__main__":
    main()
