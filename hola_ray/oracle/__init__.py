"""The Oracle: RLlib multi-agent PPO whose partner mapping follows φ (docs/contract.md §5). Building
one applies RLlib's fixes (`hola_ray.third_party`) in the driver and in each of its env runners.

`Oracle` is imported from `trainer` on first use, so that reading a run
config (`hola_ray.config.oracle`) does not import RLlib: a command validates its config
first, then imports RLlib while Ray starts (`hola_ray.run`)."""

from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.stats import TrainStats

__all__ = ["LEARNER", "Oracle", "PartnerMapping", "TrainStats", "member_module"]


def __getattr__(name: str):
    """`Oracle`, from `hola_ray.oracle.trainer` on first use."""
    if name == "Oracle":
        from hola_ray.oracle import trainer

        return getattr(trainer, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
