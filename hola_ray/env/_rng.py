"""A per-episode SplitMix64 stream, so that episode b of a batch replays exactly as a single
environment seeded alike, whatever the batch size and however other episodes reset."""

from __future__ import annotations

import numpy as np
from numba import njit

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MUL1 = np.uint64(0xBF58476D1CE4E5B9)
_MUL2 = np.uint64(0x94D049BB133111EB)
_SALT = np.uint64(0x5851F42D4C957F2D)
LAYOUT = np.uint64(0x2545F4914F6CDD1D)
"""The salt of an episode's arena draw (`side`)."""
TEAM = np.uint64(0x9FB21C651E98DF25)
"""The salt of an episode's team draws (`side`)."""


@njit(cache=True, inline="always")
def _mix(z):
    z = (z ^ (z >> np.uint64(30))) * _MUL1
    z = (z ^ (z >> np.uint64(27))) * _MUL2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def next_u64(rng, b):
    """Advance stream b of `rng` ([B] uint64) and return 64 random bits."""
    rng[b] = rng[b] + _GAMMA
    return _mix(rng[b])


@njit(cache=True, inline="always")
def uniform(rng, b):
    """A float in [0, 1) from stream b."""
    return np.float64(next_u64(rng, b) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def integer(rng, b, low, high):
    """An integer in [low, high] (both inclusive) from stream b."""
    return low + np.int64(uniform(rng, b) * (high - low + 1))


@njit(cache=True, inline="always")
def side(rng, b, salt):
    """A stream state derived from stream b's and a salt, stream b left as it is: draws of
    their own beside the stream's, which then play on as they would without them."""
    return _mix(rng[b] ^ salt)


@njit(cache=True, inline="always")
def integer_of(bits, low, high):
    """An integer in [low, high] (both inclusive) from 64 random bits."""
    return low + np.int64(
        np.float64(bits >> np.uint64(11)) * (1.0 / 9007199254740992.0) * (high - low + 1)
    )


def seed_state(seeds: np.ndarray) -> np.ndarray:
    """Initial stream states for integer seeds ([B] → [B] uint64)."""
    words = np.array([int(s) % 2**64 for s in np.ravel(seeds)], dtype=np.uint64)
    return _seed_state(words)


@njit(cache=True)
def _seed_state(seeds):
    out = np.empty_like(seeds)
    for b in range(seeds.shape[0]):
        out[b] = _mix(seeds[b] ^ _SALT)
    return out
