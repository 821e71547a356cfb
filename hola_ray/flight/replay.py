"""One episode flown as Crazyflies beside the arena's replay of it: top views of the true
paths (captures ★, crashes ✕) and the drones' height trace."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.render import PURSUER_COLOURS, draw_arena, draw_trajectory
from hola_ray.env.trajectory import Trajectory
from hola_ray.evaluation.trajectory import record
from hola_ray.flight.dynamics import Crazyflies, GuardedArena
from hola_ray.flight.guard import Guard
from hola_ray.policies.base import Policy


def _top_view(ax, config: PursuitConfig, traj: Trajectory, title: str) -> None:
    draw_arena(ax, traj.scenario(config))
    draw_trajectory(ax, config, traj)
    ax.set_title(f"{title}\n{ax.get_title()}", fontsize=9)


def draw_flight(
    config: PursuitConfig,
    team: Sequence[Policy],
    seed: int,
    path: str | Path,
    guard: Guard | None = None,
) -> dict:
    """Record episode `seed` flown and in the arena (both through `guard`, if given); write
    the figure; both metrics."""
    made: list[Crazyflies] = []

    def crazyflies(env):
        made.append(Crazyflies(env, guard=guard))
        return made[-1]

    flown = record(config, team, seed, dynamics=crazyflies)
    guarded = None if guard is None else functools.partial(GuardedArena, guard=guard)
    arena = record(config, team, seed, dynamics=guarded)
    heights = np.stack(made[0].path)[:, 0, :, 2]  # [T + 1, n_p]
    made[0].close()
    fig = Figure(figsize=(12.0, 6.2), dpi=90)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, 3, height_ratios=[4, 1.3])
    flown_title = "flown (Crazyflie 2.x, PID cascade" + (", guard)" if guard else ")")
    _top_view(fig.add_subplot(grid[0, 0]), config, flown, flown_title)
    ax = fig.add_subplot(grid[0, 1])
    arena_title = "the arena (kinematic" + (", guard)" if guard else ")")
    _top_view(ax, config, arena, f"{arena_title}, same seed and team")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, frameon=False)
    h = fig.add_subplot(grid[1, :])
    t = np.arange(heights.shape[0]) * config.dt
    for i in range(config.n_pursuers):
        h.plot(
            t, heights[:, i], color=PURSUER_COLOURS[i % len(PURSUER_COLOURS)], lw=1.0, label=f"P{i}"
        )
    h.set_xlabel("time (s)")
    h.set_ylabel("height (m)")
    h.set_title("the drones' heights (a downed drone's trace stays flat)", fontsize=9)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.93, bottom=0.08, hspace=0.35)
    fig.savefig(str(path))
    return {"flown": flown.metrics, "arena": arena.metrics}
