"""HyFoG bookkeeping, the preference hypergraph of paper Fig. 3, centrality and φ."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hola_ray.hypergraph import (
    HyFoG,
    HyFoGError,
    centrality,
    in_degree,
    lowest_centrality,
    phi,
    preference_hypergraph,
    rank_of,
    ranking,
    within_top,
)


def fig3() -> HyFoG:
    """Five nodes, l = 3, shaped like paper Fig. 3: v2 and v3 reach centrality 1.

    w(v1 v2 v3) = 10, w(v2 v3 v4) = 8, w(v2 v3 v5) = 6, w(v1 v4 v5) = 2, w(v3 v4 v5) = 1.
    Best out-edges: v1 → {1,2,3} (10 > 2); v2 → {1,2,3} (10); v3 → {1,2,3} (10);
    v4 → {2,3,4} (8 > 2, 1); v5 → {2,3,5} (6 > 2, 1).
    In-degrees (other nodes' best edges holding the node): v1: v2, v3 → 2;
    v2: v1, v3, v4, v5 → 4; v3: v1, v2, v4, v5 → 4; v4: 0; v5: 0.
    η = d / (|V| − 1) = d / 4: v1 0.5, v2 1, v3 1, v4 0, v5 0.
    """
    g = HyFoG(l=3)
    for v in ("v1", "v2", "v3", "v4", "v5"):
        g.add_node(v)
    g.set_weight(("v1", "v2", "v3"), 10)
    g.set_weight(("v2", "v3", "v4"), 8)
    g.set_weight(("v2", "v3", "v5"), 6)
    g.set_weight(("v1", "v4", "v5"), 2)
    g.set_weight(("v3", "v4", "v5"), 1)
    return g


def test_fig3_centrality():
    g = fig3()
    best = preference_hypergraph(g)
    assert best["v4"][0].nodes == ("v2", "v3", "v4") and best["v5"][0].nodes == ("v2", "v3", "v5")
    assert all(len(edges) == 1 for edges in best.values())  # one size: one out-edge each
    assert in_degree(g) == {"v1": 2, "v2": 4, "v3": 4, "v4": 0, "v5": 0}
    assert centrality(g) == {"v1": 0.5, "v2": 1.0, "v3": 1.0, "v4": 0.0, "v5": 0.0}
    assert ranking(g) == ["v2", "v3", "v1", "v4", "v5"]
    assert rank_of(g, "v3") == 1 and rank_of(g, "v1") == 3 and rank_of(g, "v5") == 4
    assert within_top(g, "v1", 3) and not within_top(g, "v4", 3)
    assert lowest_centrality(g) == "v4"


def test_ties_prefer_more_episodes_then_insertion_order():
    g = HyFoG(l=2)
    for v in "abc":
        g.add_node(v)
    g.set_weight("ab", 5.0)
    g.set_weight("ac", 5.0)
    assert preference_hypergraph(g)["a"][0].nodes == ("a", "b")  # earlier members win
    g.set_weight("ac", 5.0, episodes=3)  # same mean, more evidence
    assert preference_hypergraph(g)["a"][0].nodes == ("a", "c")


def test_teams_of_several_sizes_are_compared_within_a_size():
    """Contract §6: neither a team's summed return nor its share per member is neutral to
    the team's size, so a node prefers one team of each size, and η counts a vote per size
    (divided by their number); the HOLA-Drone_R value is the mean over sizes of the node's
    mean weight in each."""
    from hola_ray.hypergraph.phi import node_values

    g = HyFoG(l=3, max_size=4, sizes=(2, 3))
    for v in "abcd":
        g.add_node(v)
    g.set_weight("ab", 81.6)
    g.set_weight("ac", 60.0)
    g.set_weight("cd", 70.0)
    g.set_weight("abc", 121.1)
    g.set_weight("bcd", 123.0)
    best = preference_hypergraph(g)
    assert [e.nodes for e in best["a"]] == [("a", "b"), ("a", "b", "c")]
    assert [e.nodes for e in best["c"]] == [("c", "d"), ("b", "c", "d")]
    assert [e.nodes for e in best["b"]] == [("a", "b"), ("b", "c", "d")]
    # votes: a → b; a's trio → b, c; b → a; b's trio → c, d; c → d; c's trio → b, d;
    # d → c; d's trio → b, c
    assert in_degree(g) == {"a": 1, "b": 4, "c": 4, "d": 3}
    assert centrality(g) == {"a": 1 / 6, "b": 4 / 6, "c": 4 / 6, "d": 3 / 6}
    values = node_values(g, "mean_reward")
    assert values["a"] == pytest.approx(((81.6 + 60.0) / 2 + 121.1) / 2)
    assert values["d"] == pytest.approx((70.0 + 123.0) / 2)


def test_running_mean_and_removal():
    g = HyFoG(l=2, max_size=3)
    for v in (1, 2, 3):
        g.add_node(v)
    g.set_weight((1, 2), 4.0, episodes=2)
    g.set_weight((2, 1), 1.0, episodes=1)  # (4·2 + 1·1) / 3 = 3
    assert g.weight((1, 2)) == 3.0 and g.edges[0].episodes == 3
    with pytest.raises(HyFoGError, match="full"):
        g.add_node(4)
    g.set_weight((2, 3), 1.0)
    g.remove_node(2)
    assert g.nodes == [1, 3] and g.edges == []
    g.add_node(4)
    assert g.missing_edges(4) == [(1, 4), (3, 4)]


@pytest.mark.parametrize(
    ("nodes", "weight", "message"),
    [
        (("a", "b"), 1.0, "exactly l=3"),
        (("a", "a", "b"), 1.0, "repeat"),
        (("a", "b", "z"), 1.0, "unknown node"),
        (("a", "b", "c"), float("nan"), "finite"),
        (("a", "b", "c"), float("inf"), "finite"),
    ],
)
def test_bad_hyperedges_are_rejected(nodes, weight, message):
    g = HyFoG(l=3)
    for v in "abc":
        g.add_node(v)
    with pytest.raises(HyFoGError, match=message):
        g.set_weight(nodes, weight)


def test_bad_construction_and_nodes():
    with pytest.raises(HyFoGError, match="max_size"):
        HyFoG(l=3, max_size=2)
    g = HyFoG(l=2)
    g.add_node("a")
    with pytest.raises(HyFoGError, match="already"):
        g.add_node("a")
    with pytest.raises(HyFoGError, match="int or str"):
        g.add_node(("a", 1))


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_json_round_trip_is_lossless(data):
    l = data.draw(st.sampled_from([2, 3]))  # noqa: E741
    n = data.draw(st.integers(l, 7))
    g = HyFoG(l=l, max_size=10)
    ids = data.draw(
        st.lists(
            st.one_of(st.integers(-50, 50), st.text(min_size=1, max_size=4)),
            min_size=n,
            max_size=n,
            unique_by=str,
        )
    )
    ids = [i for i in ids if not isinstance(i, bool)]
    for v in ids:
        if v not in g:
            g.add_node(v)
    for nodes in itertools.combinations(g.nodes, l):
        if data.draw(st.booleans()):
            g.set_weight(
                nodes,
                data.draw(st.floats(-1e6, 1e6, allow_nan=False)),
                data.draw(st.integers(1, 100)),
            )
    back = HyFoG.from_json(g.to_json())
    assert back == g
    assert [(e.nodes, e.weight, e.episodes) for e in back.edges] == [
        (e.nodes, e.weight, e.episodes) for e in g.edges
    ]


def test_phi_is_inverse_shifted_myerson():
    g = fig3()
    # MV = Σ_{T∋i} w/3: v1 (10+2)/3 = 4, v2 (10+8+6)/3 = 8, v3 (10+8+6+1)/3 = 25/3,
    # v4 (8+2+1)/3 = 11/3, v5 (6+2+1)/3 = 3. min 3, max 25/3, δ = 0.1·16/3 = 8/15.
    # φ ∝ 1/(x − 3 + 8/15): v5 → 15/8, v4 → 1/(2/3 + 8/15) = 5/6, ...
    p = phi(g)
    raw = {
        "v1": 1 / (1 + 8 / 15),
        "v2": 1 / (5 + 8 / 15),
        "v3": 1 / (16 / 3 + 8 / 15),
        "v4": 5 / 6,
        "v5": 15 / 8,
    }
    total = sum(raw.values())
    assert p == pytest.approx({v: w / total for v, w in raw.items()})
    assert max(p, key=p.get) == "v5" and min(p, key=p.get) == "v3"


@pytest.mark.parametrize("kind", ["myerson", "mean_reward"])
def test_phi_is_a_distribution_in_edge_cases(kind):
    g = HyFoG(l=2)
    g.add_node("solo")
    assert phi(g, kind) == {"solo": 1.0}
    g.add_node("b")
    g.add_node("c")
    assert phi(g, kind) == pytest.approx({"solo": 1 / 3, "b": 1 / 3, "c": 1 / 3})  # no edges
    g.set_weight(("solo", "b"), -7.0)  # negative weights; c has no hyperedge yet
    p = phi(g, kind)
    assert sum(p.values()) == pytest.approx(1.0) and all(x > 0 for x in p.values())
    assert p["c"] == pytest.approx(1 / 3)  # ties: c takes the lowest value, all equal
    g.set_weight(("b", "c"), 0.0)
    p = phi(g, kind)
    assert sum(p.values()) == pytest.approx(1.0) and p["solo"] >= p["c"]


def test_phi_kinds_differ_when_edge_counts_differ():
    g = HyFoG(l=2)
    for v in "abcd":
        g.add_node(v)
    g.set_weight("ab", 4.0)
    g.set_weight("ac", 4.0)
    g.set_weight("cd", 3.0)
    # MV: a 4, b 2, c 3.5, d 1.5 → lowest d; mean reward: a 4, b 4, c 3.5, d 3 → lowest d
    # b: MV low (one edge) but mean reward high
    mv, mr = phi(g, "myerson"), phi(g, "mean_reward")
    assert mv["b"] > mv["c"] and mr["b"] < mr["c"]
    with pytest.raises(ValueError, match="kind"):
        phi(g, "shapley")


@settings(max_examples=40, deadline=None)
@given(
    st.integers(3, 6).flatmap(
        lambda n: st.tuples(
            st.just(n),
            st.integers(2, n - 1),
            st.lists(st.floats(-50, 50), min_size=20, max_size=20),
        )
    )
)
def test_phi_kinds_coincide_on_a_regular_hypergraph(case):
    """MV_i = Σ_{T∋i} w(T)/l = (d_i/l)·(mean reward of i): with every node in the same
    number d of hyperedges the two values differ by the factor d/l, which φ ignores. G_0
    (every l-set of the initial members) is such a hypergraph, so hola and hola_r draw the
    same partners until a member with a different degree joins (results/NOTEBOOK.md)."""
    n, l, weights = case  # noqa: E741
    g = HyFoG(l=l)
    for v in range(n):
        g.add_node(v)
    for k, nodes in enumerate(itertools.combinations(range(n), l)):
        g.set_weight(nodes, weights[k % len(weights)] + 0.01 * k)
    assert phi(g, "myerson") == pytest.approx(phi(g, "mean_reward"), rel=1e-9, abs=1e-12)


def test_draw_from_a_run_directory(tmp_path, capsys):
    from hola_ray.hypergraph import draw

    (tmp_path / "gen_001").mkdir()
    (tmp_path / "gen_001" / "hyfog.json").write_text(fig3().to_json())
    draw.main([str(tmp_path), "--out", str(tmp_path / "g.png")])
    assert (tmp_path / "g.png").stat().st_size > 10_000
    assert "wrote" in capsys.readouterr().out
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no"):
        draw.find_hyfog(tmp_path / "empty")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        draw.find_hyfog(tmp_path / "missing")
