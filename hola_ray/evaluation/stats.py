"""Small, exact statistics for episode metrics."""

from __future__ import annotations

import numpy as np


def mean_and_se(values: np.ndarray) -> tuple[float, float]:
    """Sample mean and its standard error (sample std with ddof=1 over √n; 0 for n < 2)."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if values.size == 0:
        raise ValueError("no values to average")
    mean = float(values.mean())
    if values.size < 2:
        return mean, 0.0
    return mean, float(values.std(ddof=1) / np.sqrt(values.size))


def episode_seeds(seed: int, episodes: int) -> np.ndarray:
    """Independent per-episode seeds derived from one run seed."""
    return np.random.SeedSequence(seed).generate_state(episodes, dtype=np.uint64)
