"""Compiled scalar geometry shared by the arena kernels and the hand-written policies."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def wrap(angle):
    """Angle wrapped to [−π, π) (inputs here are within a few turns of the range)."""
    while angle >= math.pi:
        angle -= 2.0 * math.pi
    while angle < -math.pi:
        angle += 2.0 * math.pi
    return angle


@njit(cache=True, inline="always")
def norm(x, y):
    """Length of (x, y); plain sqrt, several times faster than libm's overflow-safe hypot."""
    return math.sqrt(x * x + y * y)
