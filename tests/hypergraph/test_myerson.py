"""Myerson values: closed form against brute force, the Shapley axioms, and the sampler."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hola_ray.hypergraph import HyFoG, coalition_values, myerson_sample, myerson_value


@st.composite
def games(draw, max_nodes: int = 7):
    l = draw(st.sampled_from([2, 3, 4]))  # noqa: E741
    n = draw(st.integers(min_value=l, max_value=max_nodes))
    g = HyFoG(l=l, max_size=max(n, 10))
    for v in range(n):
        g.add_node(v)
    all_sets = list(itertools.combinations(range(n), l))
    chosen = draw(st.lists(st.sampled_from(all_sets), unique=True, max_size=len(all_sets)))
    weight = st.floats(min_value=-100, max_value=100, allow_nan=False, width=64)
    for nodes in chosen:
        g.set_weight(nodes, draw(weight), draw(st.integers(1, 5)))
    return g


@st.composite
def mixed_games(draw, max_nodes: int = 7):
    """Games whose hyperedges are teams of several sizes (contract §6.2)."""
    sizes = sorted(draw(st.sets(st.sampled_from([2, 3, 4, 5]), min_size=2)))
    n = draw(st.integers(min_value=sizes[-1], max_value=max_nodes))
    g = HyFoG(l=sizes[-1], max_size=max(n, 10), sizes=sizes)
    for v in range(n):
        g.add_node(v)
    all_sets = [c for k in sizes for c in itertools.combinations(range(n), k)]
    chosen = draw(st.lists(st.sampled_from(all_sets), unique=True, max_size=len(all_sets)))
    weight = st.floats(min_value=-100, max_value=100, allow_nan=False, width=64)
    for nodes in chosen:
        g.set_weight(nodes, draw(weight), draw(st.integers(1, 5)))
    return g


@settings(max_examples=60, deadline=None)
@given(st.one_of(games(), mixed_games()))
def test_closed_form_equals_brute_force(g):
    closed = myerson_value(g, "closed")
    exact = myerson_value(g, "exact")
    for v in g.nodes:
        assert closed[v] == pytest.approx(exact[v], abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.one_of(games(), mixed_games()))
def test_efficiency(g):
    # Σ_i MV_i = v(V) = Σ_T w(T)
    values = myerson_value(g, "exact")
    assert sum(values.values()) == pytest.approx(coalition_values(g)[-1], abs=1e-9)
    assert coalition_values(g)[-1] == pytest.approx(sum(e.weight for e in g.edges), abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(games(max_nodes=6))
def test_null_player_and_symmetry(g):
    values = myerson_value(g, "exact")
    incident = {v: [e for e in g.edges if v in e.nodes] for v in g.nodes}
    for v in g.nodes:
        if not incident[v]:
            assert values[v] == 0.0  # a node in no hyperedge adds nothing to any coalition
    # swap two nodes' roles: relabel every hyperedge and compare values
    a, b = g.nodes[0], g.nodes[1]
    swapped = HyFoG(l=g.l, max_size=g.max_size)
    for v in g.nodes:
        swapped.add_node(v)
    relabel = {a: b, b: a}
    for e in g.edges:
        swapped.set_weight([relabel.get(v, v) for v in e.nodes], e.weight, e.episodes)
    swapped_values = myerson_value(swapped, "exact")
    assert swapped_values[a] == pytest.approx(values[b], abs=1e-9)
    assert swapped_values[b] == pytest.approx(values[a], abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(games(max_nodes=6), st.data())
def test_additivity(g, data):
    # a second game on the same nodes: MV(w1 + w2) = MV(w1) + MV(w2)
    other = HyFoG(l=g.l, max_size=g.max_size)
    total = HyFoG(l=g.l, max_size=g.max_size)
    for v in g.nodes:
        other.add_node(v)
        total.add_node(v)
    for nodes in itertools.combinations(g.nodes, g.l):
        w2 = data.draw(st.floats(-50, 50, allow_nan=False))
        other.set_weight(nodes, w2)
        w1 = g.weight(nodes) if frozenset(nodes) in {frozenset(e.nodes) for e in g.edges} else 0.0
        total.set_weight(nodes, w1 + w2)
    a, b, ab = (myerson_value(x, "exact") for x in (g, other, total))
    for v in g.nodes:
        assert ab[v] == pytest.approx(a[v] + b[v], abs=1e-8)


@settings(max_examples=25, deadline=None)
@given(games(max_nodes=7), st.integers(0, 2**31))
def test_sampler_within_four_standard_errors(g, seed):
    exact = myerson_value(g, "exact")
    estimate, se = myerson_sample(g, samples=4000, seed=seed)
    for v in g.nodes:
        assert abs(estimate[v] - exact[v]) <= 4 * se[v] + 1e-9


def test_hand_worked_values():
    # V = {a, b, c, d}, l = 2: w(ab) = 6, w(bc) = 3, w(cd) = -3
    # MV_a = 6/2 = 3; MV_b = (6 + 3)/2 = 4.5; MV_c = (3 − 3)/2 = 0; MV_d = −3/2 = −1.5
    g = HyFoG(l=2)
    for v in "abcd":
        g.add_node(v)
    g.set_weight("ab", 6)
    g.set_weight("bc", 3)
    g.set_weight("cd", -3)
    assert myerson_value(g) == {"a": 3.0, "b": 4.5, "c": 0.0, "d": -1.5}
    assert myerson_value(g, "exact") == pytest.approx({"a": 3.0, "b": 4.5, "c": 0.0, "d": -1.5})


def test_unknown_method_and_too_large_exact():
    g = HyFoG(l=2, max_size=12)
    for v in range(10):
        g.add_node(v)
    with pytest.raises(ValueError, match="method"):
        myerson_value(g, "shapley")
    with pytest.raises(ValueError, match="exact enumeration"):
        myerson_value(g, "exact")
    assert np.isclose(sum(myerson_value(g).values()), 0.0)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from([2, 3, 4]), st.integers(4, 7), st.data())
def test_symmetric_players_get_equal_values(l, n, data):  # noqa: E741
    # nodes 0 and 1 are interchangeable: w(T) = w(swap(T)) for every hyperedge T
    g = HyFoG(l=l, max_size=10)
    for v in range(n):
        g.add_node(v)
    swap = {0: 1, 1: 0}
    drawn: dict[frozenset, float | None] = {}
    for nodes in itertools.combinations(range(n), l):
        key = frozenset(nodes)
        mirror = frozenset(swap.get(v, v) for v in nodes)
        if mirror in drawn:
            weight = drawn[mirror]
        else:
            weight = data.draw(st.one_of(st.none(), st.floats(-100, 100, allow_nan=False)))
        drawn[key] = weight
        if weight is not None:
            g.set_weight(nodes, weight)
    values = myerson_value(g, "exact")
    assert values[0] == pytest.approx(values[1], abs=1e-9)


def test_a_team_of_two_shares_its_weight_by_two_and_one_of_three_by_three():
    """Hand-worked, teams of 2 and 3: {0,1} 6, {0,1,2} 9 give MV 3 + 3 = 6, 3 + 3 = 6, 3,
    and a HyFoG of sizes 2 and 3 refuses a team of 4 and round-trips through JSON."""
    g = HyFoG(l=3, max_size=5, sizes=(2, 3))
    for v in range(4):
        g.add_node(v)
    g.set_weight((0, 1), 6.0)
    g.set_weight((0, 1, 2), 9.0)
    assert myerson_value(g, "closed") == pytest.approx({0: 6.0, 1: 6.0, 2: 3.0, 3: 0.0})
    assert myerson_value(g, "exact") == pytest.approx({0: 6.0, 1: 6.0, 2: 3.0, 3: 0.0})
    with pytest.raises(ValueError, match=r"one of \[2, 3\] nodes, got 4"):
        g.set_weight((0, 1, 2, 3), 1.0)
    assert HyFoG.from_json(g.to_json()) == g and g.sizes == (2, 3)
    assert len(g.missing_edges(3)) == 3 + 3  # {3, x} for three x, {3, x, y} for three pairs
    with pytest.raises(ValueError, match="the largest l"):
        HyFoG(l=3, sizes=(2, 4))
