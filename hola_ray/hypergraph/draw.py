"""Draw a HyFoG and its preference hypergraph to PNG.

    python -m hola_ray.hypergraph.draw RUN_DIR_OR_JSON [--out FILE.png] [--kind myerson]

Left: the HyFoG, each hyperedge a translucent polygon shaded by its weight. Right: the
preference hypergraph, an arrow from each node to the other members of its best hyperedge.
Node size grows with centrality η, node colour is φ. A run directory is searched for its
newest `*hyfog*.json`.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from hola_ray.hypergraph.hyfog import HyFoG  # noqa: E402
from hola_ray.hypergraph.phi import phi  # noqa: E402
from hola_ray.hypergraph.preference import centrality, preference_hypergraph  # noqa: E402


def find_hyfog(path: Path) -> Path:
    """The JSON itself, or the newest `*hyfog*.json` under a run directory."""
    if path.is_file():
        return path
    if path.is_dir():
        found = sorted(path.rglob("*hyfog*.json"), key=lambda p: p.stat().st_mtime)
        if found:
            return found[-1]
        raise FileNotFoundError(f"no *hyfog*.json under {path}")
    raise FileNotFoundError(f"{path} does not exist")


def draw(g: HyFoG, out: Path, kind: str = "myerson", title: str = "") -> None:
    """Write the two-panel picture of `g` to `out`."""
    nodes = g.nodes
    n = len(nodes)
    angle = {v: math.pi / 2 - 2 * math.pi * k / max(n, 1) for k, v in enumerate(nodes)}
    xy = {v: np.array([math.cos(a), math.sin(a)]) for v, a in angle.items()}
    eta = centrality(g)
    probability = phi(g, kind)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5.5), dpi=100)
    edges = g.edges
    weights = np.array([e.weight for e in edges]) if edges else np.zeros(0)
    lo, hi = (weights.min(), weights.max()) if edges else (0.0, 1.0)
    shade = plt.get_cmap("Reds")
    for e in edges:
        level = 0.5 if hi == lo else (e.weight - lo) / (hi - lo)
        pts = np.array([xy[v] for v in e.nodes])
        centre = pts.mean(axis=0)
        order = np.argsort(np.arctan2(*(pts - centre).T[::-1]))
        left.add_patch(
            Polygon(pts[order], closed=True, fc=shade(0.2 + 0.8 * level), ec="none", alpha=0.25)
        )
    best = preference_hypergraph(g)
    for source, e in best.items():
        for target in e.nodes:
            if target != source:
                right.annotate(
                    "",
                    xy=xy[target],
                    xytext=xy[source],
                    arrowprops={
                        "arrowstyle": "-|>",
                        "color": "0.4",
                        "lw": 1,
                        "alpha": 0.7,
                        "shrinkA": 12,
                        "shrinkB": 12,
                    },
                )
    colours = plt.get_cmap("viridis")
    top = max(probability.values(), default=1.0)
    for ax, heading in (
        (left, f"HyFoG: {n} nodes, {len(edges)} hyperedges (l={g.l})"),
        (right, "preference hypergraph (size: η, colour: φ)"),
    ):
        for v in nodes:
            ax.scatter(
                *xy[v],
                s=200 + 1200 * eta.get(v, 0.0),
                color=colours(probability[v] / top),
                edgecolors="black",
                zorder=3,
            )
            ax.annotate(
                f"{v}\nη={eta.get(v, 0):.2f} φ={probability[v]:.2f}",
                xy[v] * 1.25,
                ha="center",
                va="center",
                fontsize=7,
            )
        ax.set_title(heading, fontsize=10)
        ax.set_xlim(-1.6, 1.6)
        ax.set_ylim(-1.6, 1.6)
        ax.set_aspect("equal")
        ax.axis("off")
    mappable = plt.cm.ScalarMappable(cmap=colours, norm=plt.Normalize(0, top))
    fig.colorbar(mappable, ax=right, fraction=0.04, label=f"φ ({kind})")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.savefig(out)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m hola_ray.hypergraph.draw", description=__doc__)
    parser.add_argument("source", type=Path, help="a HyFoG JSON file or a run directory")
    parser.add_argument("--out", type=Path, help="PNG to write (default: beside the JSON)")
    parser.add_argument("--kind", default="myerson", choices=["myerson", "mean_reward"])
    args = parser.parse_args(argv)
    path = find_hyfog(args.source)
    g = HyFoG.from_json(path.read_text())
    out = args.out or path.with_suffix(".png")
    draw(g, out, args.kind, title=str(path))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
