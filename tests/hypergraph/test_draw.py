"""The HyFoG picture: a readable weight map (mean weight per node pair) beside the
preference hypergraph, written outside the completed generation folders."""

from __future__ import annotations

import numpy as np

from hola_ray.hypergraph.draw import default_out, draw, main, pair_weights
from hola_ray.hypergraph.hyfog import HyFoG


def small() -> HyFoG:
    g = HyFoG(l=3, max_size=5)
    for v in range(5):
        g.add_node(v)
    g.set_weight((0, 1, 2), 6.0)
    g.set_weight((0, 1, 3), 2.0)
    g.set_weight((2, 3, 4), -4.0)
    return g


def test_pair_weights_are_the_mean_of_the_hyperedges_holding_both():
    nodes, m = pair_weights(small())
    assert nodes == [0, 1, 2, 3, 4]
    assert m[0, 1] == m[1, 0] == 4.0  # (6 + 2) / 2
    assert m[0, 2] == 6.0 and m[2, 4] == -4.0 and m[2, 2] == 1.0  # (6 − 4) / 2
    assert m[0, 0] == 4.0 and m[4, 4] == -4.0
    assert np.isnan(m[0, 4]) and np.isnan(m[1, 4])  # no hyperedge holds them both


def test_the_picture_of_a_generation_goes_to_the_run_directory(tmp_path):
    gen = tmp_path / "run" / "generations" / "gen_0003"
    gen.mkdir(parents=True)
    (gen / "hyfog.json").write_text(small().to_json())
    assert default_out(gen / "hyfog.json") == tmp_path / "run" / "hyfog_gen_0003.png"
    main([str(tmp_path / "run")])
    assert (tmp_path / "run" / "hyfog_gen_0003.png").stat().st_size > 0
    assert sorted(p.name for p in gen.iterdir()) == ["hyfog.json"]  # the folder untouched
    draw(small(), tmp_path / "x.png")
    assert (tmp_path / "x.png").stat().st_size > 0
