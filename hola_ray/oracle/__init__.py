"""The Oracle: RLlib multi-agent PPO whose partner mapping follows φ (SPEC §5).

Importing it applies `hola_ray.rllib_fixes.fast_connectors` and `light_seeding` in this
process (the driver and every env runner, which imports `hola_ray.oracle.batched_runner`)."""

from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.trainer import Oracle, TrainStats
from hola_ray.rllib_fixes import fast_connectors, light_seeding

fast_connectors()
light_seeding()

__all__ = ["LEARNER", "Oracle", "PartnerMapping", "TrainStats", "member_module"]
