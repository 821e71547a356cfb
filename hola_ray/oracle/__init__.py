"""The Oracle: RLlib multi-agent PPO whose partner mapping follows φ (SPEC §5). Building
one applies `hola_ray.rllib_fixes` in the driver and in each of its env runners."""

from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.trainer import Oracle, TrainStats

__all__ = ["LEARNER", "Oracle", "PartnerMapping", "TrainStats", "member_module"]
