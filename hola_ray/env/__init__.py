"""The pursuit arena: its config, batched core and PettingZoo face (docs/contract.md §1–§2)."""

from hola_ray.env.config import ConfigError, EvaderConfig, PursuitConfig
from hola_ray.env.core import INITIAL_STATE_KEYS, BatchedPursuit, StepResult
from hola_ray.env.layout import ObsLayout

__all__ = [
    "INITIAL_STATE_KEYS",
    "BatchedPursuit",
    "ConfigError",
    "EvaderConfig",
    "ObsLayout",
    "PursuitConfig",
    "StepResult",
]
