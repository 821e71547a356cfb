"""The Oracle: RLlib multi-agent PPO whose partner mapping follows φ (SPEC §5)."""

from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.trainer import Oracle, TrainStats

__all__ = ["LEARNER", "Oracle", "PartnerMapping", "TrainStats", "member_module"]
