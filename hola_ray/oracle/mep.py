"""MEP's population-entropy bonus (paper Eq. 2) as a learner-connector piece.

The objective R + α·H(π̄(·|s)) with π̄ the mean policy of the population is optimised, as
in MEP (Zhao et al. 2023), through the per-step reward bonus −α·log π̄(a_t|s_t). Members
act in equal shares, so the bonus averaged over them is an unbiased estimate of H(π̄):
Σ_k (1/K)·E_{a∼π_k}[−log π̄(a|s)] = E_{a∼π̄}[−log π̄(a|s)]. It is added to the rewards
of every population module before GAE, so it flows into the advantages and value
targets like any other reward.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.connectors.learner.general_advantage_estimation import GeneralAdvantageEstimation
from ray.rllib.core.columns import Columns


class PopulationEntropyBonus(ConnectorV2):
    """Adds −α·log π̄(a|s) to the rewards of each population module in the train batch."""

    def __init__(
        self,
        input_observation_space=None,
        input_action_space=None,
        *,
        alpha: float,
        module_ids: Sequence[str],
        **kwargs: Any,
    ):
        super().__init__(input_observation_space, input_action_space, **kwargs)
        self.alpha = alpha
        self.module_ids = list(module_ids)

    def __call__(self, *, rl_module, batch, episodes, **kwargs):
        members = [m for m in self.module_ids if m in rl_module.keys()]
        if not members or self.alpha == 0.0:
            return batch
        with torch.no_grad():
            for mid in members:
                if mid not in batch:
                    continue
                bonus = -self.alpha * mean_policy_logp(
                    rl_module, members, batch[mid][Columns.OBS], batch[mid][Columns.ACTIONS]
                )
                rewards = batch[mid][Columns.REWARDS]
                batch[mid][Columns.REWARDS] = rewards + bonus.to(rewards.dtype)
        return batch


def mean_policy_logp(rl_module, members: Sequence[str], obs, actions) -> torch.Tensor:
    """log π̄(a|s) = log mean_k π_k(a|s) over the members' action distributions, [T]."""
    logps = []
    for k in members:
        module = rl_module[k]
        inputs = module.forward_inference({Columns.OBS: obs})[Columns.ACTION_DIST_INPUTS]
        dist = module.get_inference_action_dist_cls().from_logits(inputs)
        logps.append(dist.logp(actions))
    return torch.logsumexp(torch.stack(logps), dim=0) - math.log(len(members))


class MEPLearner(PPOTorchLearner):
    """PPO learner whose pipeline adds the population-entropy bonus before GAE.

    Reads `mep_alpha` and `mep_modules` from `learner_config_dict`.
    """

    def build(self) -> None:
        super().build()
        extra = self.config.learner_config_dict
        alpha = float(extra.get("mep_alpha", 0.0))
        if alpha > 0.0 and self._learner_connector is not None:
            self._learner_connector.insert_before(
                GeneralAdvantageEstimation,
                PopulationEntropyBonus(alpha=alpha, module_ids=extra["mep_modules"]),
            )
