"""The pursuit arena: its batched core and PettingZoo face (docs/contract.md §1–§2); its
config (`hola_ray.config.scenario`) is re-exported here for the arena's users."""

from hola_ray.config.layout import ObsLayout
from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import EvaderConfig, PursuitConfig
from hola_ray.env.core import INITIAL_STATE_KEYS, BatchedPursuit, StepResult

__all__ = [
    "INITIAL_STATE_KEYS",
    "BatchedPursuit",
    "ConfigError",
    "EvaderConfig",
    "ObsLayout",
    "PursuitConfig",
    "StepResult",
]
