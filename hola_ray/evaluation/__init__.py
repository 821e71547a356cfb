"""Metrics, rollouts and tables over the batched core (docs/contract.md §1 metrics, paper §V)."""

from hola_ray.evaluation.rollout import RolloutResult, rollout
from hola_ray.evaluation.stats import episode_seeds, mean_and_se

__all__ = ["RolloutResult", "episode_seeds", "mean_and_se", "rollout"]
