"""Compiled helpers that read a pursuer's observation in its own frame (x ahead, y left)."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def point(obs, n, k, scale):
    """(x, y, distance) in metres of the (distance, bearing) pair at obs[n, k:k+2]."""
    d = obs[n, k] * scale
    a = obs[n, k + 1] * math.pi
    return d * math.cos(a), d * math.sin(a), d


@njit(cache=True)
def nearest_live_evader(obs, n, n_evaders, far):
    """Index of the nearest live evader of row n, or −1 when all are captured."""
    best = -1
    best_d = far
    for e in range(n_evaders):
        d = obs[n, 3 * e]
        if d < best_d:
            best, best_d = e, d
    return best


@njit(cache=True, inline="always")
def turn_action(turn, max_turn):
    """The action in [0, 1] whose heading change (2a − 1)·max_turn is nearest to `turn`
    (the arena's action rule, docs/contract.md §1)."""
    return min(max(0.5 + turn / (2.0 * max_turn), 0.0), 1.0)


@njit(cache=True, inline="always")
def to_action(fx, fy, max_turn):
    """Action in [0, 1] turning toward direction (fx, fy) of the own frame; 0.5 if zero."""
    if fx == 0.0 and fy == 0.0:
        return 0.5
    return turn_action(math.atan2(fy, fx), max_turn)


@njit(cache=True, inline="always")
def repel(
    fx, fy, obs, n, k_obst, k_mates, n_mates, scale, far,
    obst_range, obst_gain, mate_range, mate_gain,
):  # fmt: skip
    """(fx, fy) less a soft repulsion from the nearest obstacle point nearer than
    `obst_range` and from each seen teammate nearer than `mate_range`: each a unit vector
    away from it, weighted gain · (range − distance) / range."""
    qx, qy, d = point(obs, n, k_obst, scale)
    if 0.0 < d < obst_range:
        w = obst_gain * (obst_range - d) / obst_range
        fx -= w * qx / d
        fy -= w * qy / d
    for j in range(n_mates):
        k = k_mates + 2 * j
        if obs[n, k] >= far:
            continue
        mx, my, md = point(obs, n, k, scale)
        if 0.0 < md < mate_range:
            w = mate_gain * (mate_range - md) / mate_range
            fx -= w * mx / md
            fy -= w * my / md
    return fx, fy
