"""The metric spec: every figure the project reports, named once.

Two families:
- `TEAM`: a team's rollout, every seat (the Grapher's hyperedge weights and figures, the
  self-play judging, the population's own teams, Table II): per-episode values read off a
  `RolloutResult`, each reported as its mean with a standard error.
- `ZERO_SHOT`: a learner seated among drawn teammates (the zero-shot evaluation and the
  validation teammates): per-episode values computed by `zero_shot_values`; their means and
  intervals are what `evaluate`, `experiment`, `status` and every table show
  (`hola_ray.evaluation.compare`).

A new figure is one entry here (and, when it needs data a rollout does not record yet, the
field in `RolloutResult`); the rollout summary, the edge results, the generation log, the
evaluation and the experiment's tables read it from here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Metric:
    name: str
    """its name in metrics.csv columns (`learner_<name>`), tables and results"""
    field: str
    """the `RolloutResult` field (team metrics) or per-episode record (zero-shot) it reads"""
    doc: str


TEAM: tuple[Metric, ...] = (
    Metric("success", "success", "every evader captured before the horizon"),
    Metric("return", "team_return", "the pursuers' summed return (the hyperedge weight)"),
    Metric("collision", "collision", "at least one pursuer crashed"),
    Metric("length", "length", "steps until the episode ended (the horizon when cut)"),
)
"""A team's figures, in the order metrics.csv lists them."""


def team_figures(result) -> dict[str, float]:
    """The mean of each `TEAM` metric over a rollout's episodes, keyed by field."""
    return {m.field: float(np.mean(getattr(result, m.field))) for m in TEAM}


def _share(hits: np.ndarray, seats: np.ndarray) -> np.ndarray:
    """[E] the share of each row's `seats` that `hits` marks (0 for a row with none)."""
    count = seats.sum(axis=1)
    return np.where(count > 0, hits.sum(axis=1) / np.maximum(count, 1), 0.0)


_ZERO_SHOT: dict[str, tuple[str, Callable[..., np.ndarray]]] = {
    "success": ("every evader captured", lambda r, seat, n_p: r.success.astype(np.float64)),
    "collision": ("any seat crashed", lambda r, seat, n_p: r.collision.astype(np.float64)),
    "length": (
        "steps, the horizon when truncated",
        lambda r, seat, n_p: r.length.astype(np.float64),
    ),
    "reward": (
        "the mean per-pursuer return over the pursuers in play (AT-Drone's REW)",
        lambda r, seat, n_p: r.team_return / np.maximum(r.played.sum(axis=1), 1),
    ),
    "learner_crash": (
        "the learner's own seat crashed (one of its seats, where it plays several)",
        lambda r, seat, n_p: (r.crashed & seat).any(axis=1).astype(np.float64),
    ),
    "teammate_crash": (
        "the share of teammate seats in play that crashed",
        lambda r, seat, n_p: _share(r.crashed & ~seat, r.played & ~seat),
    ),
}

ZERO_SHOT: tuple[Metric, ...] = tuple(Metric(k, k, doc) for k, (doc, _) in _ZERO_SHOT.items())
"""A learner among drawn teammates: per-episode values whose figure is their mean."""


def zero_shot_values(result, learner_seat: np.ndarray, n_p: int) -> dict[str, np.ndarray]:
    """Each `ZERO_SHOT` metric's per-episode values of a rollout in which `learner_seat`
    ([episodes, n_p] bool: one True per row, or its fixed seats) marks the learner."""
    return {name: fn(result, learner_seat, n_p) for name, (_, fn) in _ZERO_SHOT.items()}


VALIDATED = ("success", "collision", "learner_crash", "length")
"""The `ZERO_SHOT` figures every generation logs with the validation teammates (`val_<name>`
in metrics.csv; best.pt is chosen on success, then collision)."""
