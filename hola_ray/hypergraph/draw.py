"""Draw a HyFoG and its preference hypergraph to PNG.

    python -m hola_ray.hypergraph.draw RUN_DIR_OR_JSON [--out FILE.png] [--kind myerson]

Left: the HyFoG's weights as a node × node heat map: cell (i, j) is the mean weight (team
return) of the hyperedges that hold both i and j, the diagonal the mean of i's hyperedges;
blank where no hyperedge holds the pair. Right: the preference hypergraph, an arrow from
each node to the other members of its best hyperedge; node size grows with centrality η,
node colour is φ. A run directory is searched for its newest `*hyfog*.json`, and the
picture goes to the run directory itself (`hyfog_gen_NNNN.png`), never into a completed
generation folder.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from hola_ray.hypergraph.hyfog import HyFoG
from hola_ray.hypergraph.phi import phi
from hola_ray.hypergraph.preference import centrality, preference_hypergraph


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


def pair_weights(g: HyFoG) -> tuple[list, np.ndarray]:
    """(nodes, [n, n] matrix): the mean weight of the hyperedges holding both nodes (the
    diagonal: holding the node), NaN where none does."""
    nodes = list(g.nodes)
    index = {v: k for k, v in enumerate(nodes)}
    total = np.zeros((len(nodes), len(nodes)))
    count = np.zeros((len(nodes), len(nodes)))
    for members, weight in g.weights():
        ks = [index[v] for v in members]
        for i in ks:
            for j in ks:
                total[i, j] += weight
                count[i, j] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        return nodes, np.where(count > 0, total / np.maximum(count, 1), np.nan)


def default_out(path: Path) -> Path:
    """Where the picture of a HyFoG JSON goes: beside it, except inside a generation folder
    (`gen_NNNN/`), which a run completed and never changes: then the run directory."""
    if path.parent.name.startswith("gen_") and path.parent.parent.name == "generations":
        return path.parent.parent.parent / f"hyfog_{path.parent.name}.png"
    return path.with_suffix(".png")


def draw(g: HyFoG, out: Path, kind: str = "myerson", title: str = "") -> None:
    """Write the two-panel picture of `g` to `out`."""
    nodes = g.nodes
    n = len(nodes)
    angle = {v: math.pi / 2 - 2 * math.pi * k / max(n, 1) for k, v in enumerate(nodes)}
    xy = {v: np.array([math.cos(a), math.sin(a)]) for v, a in angle.items()}
    eta = centrality(g)
    probability = phi(g, kind)
    fig = Figure(figsize=(12, 5.5), dpi=100)  # no pyplot, no global backend switched
    left, right = fig.subplots(1, 2)
    edges = g.edges
    order, matrix = pair_weights(g)
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="0.92")
    image = left.imshow(np.ma.masked_invalid(matrix), cmap=cmap)
    left.set_xticks(range(n), [str(v) for v in order], fontsize=8)
    left.set_yticks(range(n), [str(v) for v in order], fontsize=8)
    if n <= 12:
        finite = matrix[np.isfinite(matrix)]
        middle = (finite.min() + finite.max()) / 2 if finite.size else 0.0
        for i in range(n):
            for j in range(n):
                if np.isfinite(matrix[i, j]):
                    left.text(
                        j,
                        i,
                        f"{matrix[i, j]:.1f}",
                        ha="center",
                        va="center",
                        fontsize=7,
                        color="white" if matrix[i, j] < middle else "black",
                    )
    fig.colorbar(image, ax=left, fraction=0.046, label="mean hyperedge weight (team return)")
    colours = matplotlib.colormaps["plasma"]
    top = max(probability.values(), default=1.0)
    best = preference_hypergraph(g)
    for source, edges in best.items():
        for target in dict.fromkeys(v for e in edges for v in e.nodes):
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
    left.set_title(
        f"HyFoG: {n} nodes, {len(edges)} hyperedges (l={g.l}); mean weight per pair",
        fontsize=10,
    )
    for v in nodes:
        right.scatter(
            *xy[v],
            s=200 + 1200 * eta.get(v, 0.0),
            color=colours(probability[v] / top),
            edgecolors="black",
            zorder=3,
        )
        right.annotate(
            f"{v}\nη={eta.get(v, 0):.2f} φ={probability[v]:.2f}",
            xy[v] * 1.25,
            ha="center",
            va="center",
            fontsize=7,
        )
    right.set_title("preference hypergraph (size: η, colour: φ)", fontsize=10)
    right.set_xlim(-1.6, 1.6)
    right.set_ylim(-1.6, 1.6)
    right.set_aspect("equal")
    right.axis("off")
    mappable = ScalarMappable(cmap=colours, norm=Normalize(0, top))
    fig.colorbar(mappable, ax=right, fraction=0.04, label=f"φ ({kind})")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.savefig(out)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m hola_ray.hypergraph.draw", description=__doc__)
    parser.add_argument("source", type=Path, help="a HyFoG JSON file or a run directory")
    parser.add_argument(
        "--out", type=Path, help="PNG to write (default: the run directory, or beside the JSON)"
    )
    parser.add_argument("--kind", default="myerson", choices=["myerson", "mean_reward"])
    args = parser.parse_args(argv)
    path = find_hyfog(args.source)
    g = HyFoG.from_json(path.read_text())
    out = args.out or default_out(path)
    draw(g, out, args.kind, title=str(path))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
