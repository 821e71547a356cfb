"""What one `Oracle.train` call did (`TrainStats`): plain figures, importable without RLlib."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrainStats:
    """What one `Oracle.train` call did."""

    env_steps: int
    """environment steps sampled in this call"""
    iterations: int
    """PPO updates"""
    wall_s: float
    """seconds spent in `algo.train()`"""
    sample_s: float
    """of which sampling: everything but the learner update (weight sync included)"""
    learn_s: float
    """of which the learner update (GAE pipeline and SGD), timed in `OracleLearner`"""
    episode_return: float
    """mean summed team return of the last iteration's episodes (NaN if none ended)"""
    module_return: dict[str, float]
    """mean return per module over the last iteration's episodes"""
    learner_samples: int = 0
    """transitions of the trained module(s) the learner consumed in this call (every seat
    a trained module played, every step it acted)"""
    gradient_steps: int = 0
    """minibatch gradient steps applied to the trained module(s) in this call"""
    iteration_log: tuple[dict[str, float], ...] = ()
    """one row per PPO iteration: env steps so far, return, the trained policies' spread
    (`MLPPolicy.spread` on reference observations, the widest trained module), entropy,
    value loss and explained variance (KL when the KL penalty is on)"""

    @classmethod
    def untrained(cls) -> TrainStats:
        """No training: a generation 0 made of copies, or a build resumed after its end."""
        return cls(0, 0, 0.0, 0.0, 0.0, float("nan"), {})

    @property
    def spread(self) -> dict[str, float]:
        """The last iteration's spread and the widest of the call: std_median, clipped,
        std_median_max, clipped_max."""
        if not self.iteration_log:
            return {}
        last = self.iteration_log[-1]
        return {
            "std_median": last["std_median"],
            "clipped": last["clipped"],
            "std_median_max": max(r["std_median"] for r in self.iteration_log),
            "clipped_max": max(r["clipped"] for r in self.iteration_log),
        }

    @property
    def env_steps_per_s(self) -> float:
        return self.env_steps / max(self.wall_s, 1e-9)

    @property
    def sampled_steps_per_s(self) -> float:
        return self.env_steps / max(self.sample_s, 1e-9)
