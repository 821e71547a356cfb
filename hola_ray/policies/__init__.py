"""Every pursuer policy behind one interface (contract §3): hand-written teammates and learned
pursuers exported from RLlib (`MLPPolicy`, plain torch)."""

from hola_ray.policies.apf import APFA, APFConfig, apf_actions
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy, GreedyConfig
from hola_ray.policies.learned import MLPPolicy, export_from_rllib
from hola_ray.policies.registry import make_policy, policy_names
from hola_ray.policies.vicsek import Vicsek, VicsekConfig

__all__ = [
    "APFA",
    "APFConfig",
    "Greedy",
    "GreedyConfig",
    "MLPPolicy",
    "Policy",
    "Vicsek",
    "VicsekConfig",
    "apf_actions",
    "export_from_rllib",
    "make_policy",
    "policy_names",
]
