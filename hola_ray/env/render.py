"""Drawing the arena with matplotlib: frames, trajectory plots and animated GIFs."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib import patches
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hola_ray.config.scenario import PursuitConfig

if TYPE_CHECKING:
    from hola_ray.env.core import BatchedPursuit
    from hola_ray.env.trajectory import Trajectory

PURSUER_COLOURS = ("#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#bcbd22")
EVADER_COLOURS = ("#1f77b4", "#17becf", "#2ca02c", "#7f7f7f")


def _colour(palette: tuple[str, ...], i: int) -> str:
    return palette[i % len(palette)]


def draw_arena(ax: Axes, config: PursuitConfig) -> None:
    """Walls, boxes, discs and the two spawn regions."""
    w, h = config.arena_width, config.arena_height
    ax.add_patch(patches.Rectangle((0, 0), w, h, fill=False, lw=2, ec="black"))
    for cx, cy, bw, bh in config.obstacles:
        ax.add_patch(patches.Rectangle((cx - bw / 2, cy - bh / 2), bw, bh, color="black"))
    for cx, cy, r in config.discs:
        ax.add_patch(patches.Circle((cx, cy), r, color="black"))
    for region, colour in ((config.pursuer_spawn, "#d62728"), (config.evader_spawn, "#1f77b4")):
        x0, x1, y0, y1 = region
        ax.add_patch(
            patches.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", lw=0.8, ec=colour)
        )
    ax.set_xlim(-0.1, w + 0.1)
    ax.set_ylim(-0.1, h + 0.1)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def _figure(config: PursuitConfig, height_in: float = 6.0) -> tuple[Figure, Axes]:
    ratio = (config.arena_width + 0.2) / (config.arena_height + 0.2)
    # a Figure of its own on the Agg canvas: no pyplot, no global backend switched
    fig = Figure(figsize=(height_in * ratio + 0.2, height_in + 0.4), dpi=80)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.02, top=0.93)
    draw_arena(ax, config)
    return fig, ax


def _canvas_rgb(fig: Figure) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def render_frame(config: PursuitConfig, core: BatchedPursuit, b: int) -> np.ndarray:
    """An RGB image [H, W, 3] of episode b's current state, in the arena it is played in;
    a pursuer out of play (landed, or yet to join) is not drawn."""
    fig, ax = _figure(core.config_of(b), 4.0)
    for i in range(config.n_pursuers):
        if not core.pursuer_present[b, i]:
            continue
        x, y = core.pursuer_pos[b, i]
        marker = "o" if core.pursuer_active[b, i] else "X"
        ax.plot(x, y, marker, color=_colour(PURSUER_COLOURS, i), ms=8)
    for e in range(config.n_evaders):
        if core.evader_alive[b, e]:
            x, y = core.evader_pos[b, e]
            ax.plot(x, y, "^", color=_colour(EVADER_COLOURS, e), ms=8)
    ax.set_title(f"t = {int(core.t[b])}", fontsize=9)
    image = _canvas_rgb(fig)
    return image


def draw_trajectory(ax: Axes, config: PursuitConfig, traj: Trajectory) -> None:
    """Every drone's path with capture (★) and collision (✕) marks, and the metrics as the
    title, on `ax` (the arena already drawn)."""
    present = traj.present()
    for i in range(config.n_pursuers):
        colour = _colour(PURSUER_COLOURS, i)
        xy = np.where(present[:, i, None], traj.pursuer_pos[:, i], np.nan)  # in play only
        ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=1.2, label=f"P{i} {traj.policy_names[i]}")
        flying = np.flatnonzero(present[:, i])
        if flying.size:  # where it started, or joined
            ax.plot(*xy[flying[0]], "o", color=colour, ms=6)
    for e in range(config.n_evaders):
        colour = _colour(EVADER_COLOURS, e)
        steps = np.flatnonzero(traj.evader_alive[:, e])
        last = int(steps[-1]) + 2 if steps.size else 1
        xy = traj.evader_pos[:last, e]
        ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=1.2, label=f"E{e}")
        ax.plot(*xy[0], "^", color=colour, ms=7)
    for step, _, where in traj.captures:
        ax.plot(*where, "*", color="gold", mec="black", ms=16, zorder=5)
        ax.annotate(
            f"caught t={step}", where, xytext=(5, 5), textcoords="offset points", fontsize=7
        )
    for step, _, where in traj.collisions:
        ax.plot(*where, "X", color="black", ms=12, zorder=5)
        ax.annotate(
            f"crash t={step}", where, xytext=(5, -10), textcoords="offset points", fontsize=7
        )
    m = traj.metrics
    ax.set_title(
        f"success={m['success']} collision={m['collision']} length={m['length']}", fontsize=9
    )


def plot_trajectory(config: PursuitConfig, traj: Trajectory, path: str) -> None:
    """A PNG of every drone's path with capture (★) and collision (✕) marks, in the arena
    the episode was played in."""
    fig, ax = _figure(traj.scenario(config))
    draw_trajectory(ax, config, traj)
    fig.subplots_adjust(bottom=0.1)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, fontsize=6, frameon=False)
    fig.savefig(path)


def animate_trajectory(
    config: PursuitConfig, traj: Trajectory, path: str, stride: int = 2, fps: int = 20
) -> int:
    """An animated GIF of the episode (every `stride`-th step); returns the frame count."""
    from PIL import Image

    fig, ax = _figure(traj.scenario(config), 4.5)
    n_p, n_e = config.n_pursuers, config.n_evaders
    present = traj.present()
    trails = [ax.plot([], [], "-", color=_colour(PURSUER_COLOURS, i), lw=1)[0] for i in range(n_p)]
    trails += [ax.plot([], [], "-", color=_colour(EVADER_COLOURS, e), lw=1)[0] for e in range(n_e)]
    pursuers = [
        ax.plot([], [], "o", color=_colour(PURSUER_COLOURS, i), ms=7, label=f"P{i} {name}")[0]
        for i, name in enumerate(traj.policy_names)
    ]
    evaders = [ax.plot([], [], "^", color=_colour(EVADER_COLOURS, e), ms=7)[0] for e in range(n_e)]
    capture_marks = ax.plot([], [], "*", color="gold", mec="black", ms=14, ls="")[0]
    crash_marks = ax.plot([], [], "X", color="black", ms=10, ls="")[0]
    title = ax.set_title("", fontsize=9)
    # which policy plays each seat
    ax.legend(
        handles=pursuers,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        ncol=3,
        fontsize=6,
        frameon=False,
    )
    fig.subplots_adjust(bottom=0.1)
    tail = 60
    steps = list(range(0, traj.steps + 1, stride))
    if steps[-1] != traj.steps:
        steps.append(traj.steps)
    images = []
    for t in steps:
        lo = max(0, t - tail)
        for i in range(n_p):
            seen = present[lo : t + 1, i, None]
            trail = np.where(seen, traj.pursuer_pos[lo : t + 1, i], np.nan)
            trails[i].set_data(trail[:, 0], trail[:, 1])
            x, y = traj.pursuer_pos[t, i]
            pursuers[i].set_data([x], [y])
            pursuers[i].set_marker("o" if traj.pursuer_active[t, i] else "X")
            pursuers[i].set_visible(bool(present[t, i]))
        for e in range(n_e):
            trails[n_p + e].set_data(
                traj.evader_pos[lo : t + 1, e, 0], traj.evader_pos[lo : t + 1, e, 1]
            )
            x, y = traj.evader_pos[t, e]
            evaders[e].set_data([x], [y])
            evaders[e].set_visible(bool(traj.evader_alive[t, e]))
        caught = [where for step, _, where in traj.captures if step <= t]
        crashed = [where for step, _, where in traj.collisions if step <= t]
        capture_marks.set_data([w[0] for w in caught], [w[1] for w in caught])
        crash_marks.set_data([w[0] for w in crashed], [w[1] for w in crashed])
        title.set_text(f"t = {t} / {traj.steps}   caught {len(caught)}/{n_e}")
        images.append(Image.fromarray(_canvas_rgb(fig)))
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        duration=int(1000 / fps),
        loop=0,
        optimize=False,
    )
    return len(images)


def arenas_figure(path: str) -> None:
    """The named arenas side by side, their spawn strips dashed (docs/open-teams.md)."""
    from hola_ray.config.scenario import ARENAS

    fig = Figure(figsize=(2.5 * len(ARENAS), 3.6))
    FigureCanvasAgg(fig)
    for k, name in enumerate(ARENAS):
        ax = fig.add_subplot(1, len(ARENAS), k + 1)
        draw_arena(ax, PursuitConfig(arena=name))
        ax.set_title(name)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
