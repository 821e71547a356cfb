"""Every pursuer policy behind one interface (SPEC §3): hand-written teammates for now."""

from hola_ray.policies.apf import APFA, APFConfig, apf_actions
from hola_ray.policies.base import Policy, turn_to_action
from hola_ray.policies.greedy import Greedy, GreedyConfig
from hola_ray.policies.registry import make_policy, policy_names
from hola_ray.policies.vicsek import Vicsek, VicsekConfig

__all__ = [
    "APFA",
    "APFConfig",
    "Greedy",
    "GreedyConfig",
    "Policy",
    "Vicsek",
    "VicsekConfig",
    "apf_actions",
    "make_policy",
    "policy_names",
    "turn_to_action",
]
