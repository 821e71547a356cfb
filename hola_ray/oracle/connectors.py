"""The Oracle's learner-connector pieces: MEP's population-entropy bonus (paper Eq. 2),
the frozen partners' rows dropped before GAE, and PPO's bootstrap timestep added as
arrays.

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

import numpy as np
import torch
from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.connectors.learner.add_one_ts_to_episodes_and_truncate import (
    AddOneTsToEpisodesAndTruncate,
)
from ray.rllib.core.columns import Columns
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.utils.postprocessing.episodes import add_one_ts_to_episodes_and_truncate


def mean_policy_logp(rl_module, members: Sequence[str], obs, actions) -> torch.Tensor:
    """log π̄(a|s) = log mean_k π_k(a|s) over the members' action distributions, [T]."""
    logps = []
    for k in members:
        module = rl_module[k]
        inputs = module.forward_inference({Columns.OBS: obs})[Columns.ACTION_DIST_INPUTS]
        dist = module.get_inference_action_dist_cls().from_logits(inputs)
        logps.append(dist.logp(actions))
    return torch.logsumexp(torch.stack(logps), dim=0) - math.log(len(members))


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


class DropFrozenModules(ConnectorV2):
    """Removes the frozen partners' rows from the train batch before GAE.

    RLlib's GAE connector computes critic values for every module in the batch (its own
    TODO says the filter to trained modules belongs in the pipeline), and the learner
    drops the frozen modules' rows only afterwards, before its minibatches. With ten
    frozen partners that is two thirds of the rows run through a critic for nothing."""

    def __init__(
        self,
        input_observation_space=None,
        input_action_space=None,
        *,
        trained: Sequence[str],
        **kwargs: Any,
    ):
        super().__init__(input_observation_space, input_action_space, **kwargs)
        self.trained = frozenset(trained)

    def __call__(self, *, rl_module, batch, episodes, **kwargs):
        for mid in [m for m in batch if m not in self.trained]:
            del batch[mid]
        return batch


class AddOneTsInArrays(AddOneTsToEpisodesAndTruncate):
    """RLlib's `AddOneTsToEpisodesAndTruncate` (PPO's first learner-connector piece: each
    episode chunk gains one bootstrap timestep, masked out of the loss), adding its three
    columns per chunk as one numpy array each where RLlib adds Python lists item by item
    (`add_n_batch_items` then calls `add_batch_item` once per timestep, and the batching
    piece later stacks the items one by one). The same batch, in the same order (tested
    against RLlib's own in tests/oracle/test_oracle.py); its cost was the larger part of the
    learner pipeline's."""

    def __call__(self, *, rl_module, batch, episodes, explore=None, shared_data=None, **kw):
        if isinstance(episodes[0], MultiAgentEpisode):  # as RLlib: each chunk its own id
            for i, ma_episode in enumerate(episodes):
                ma_episode.id_ += "_" + str(i)
                for sa_episode in ma_episode.agent_episodes.values():
                    sa_episode.multi_agent_episode_id = ma_episode.id_
        for i, sa_episode in enumerate(
            self.single_agent_episode_iterator(episodes, agents_that_stepped_only=False)
        ):
            sa_episode.id_ += "_" + str(i)
            length = len(sa_episode)
            if length < 1:  # RLlib's own refuses such a chunk too (its lists mismatch)
                raise ValueError(f"episode chunk {sa_episode.id_} has no timestep")
            add_one_ts_to_episodes_and_truncate([sa_episode])
            loss_mask = np.ones(length + 1, dtype=bool)
            loss_mask[-1] = False  # the appended bootstrap timestep
            terminateds = np.zeros(length + 1, dtype=bool)
            terminateds[length - 1] = bool(sa_episode.is_terminated)
            truncateds = np.zeros(length + 1, dtype=bool)
            truncateds[length - 1] = bool(sa_episode.is_truncated)
            for column, items in (
                (Columns.LOSS_MASK, loss_mask),
                (Columns.TERMINATEDS, terminateds),
                (Columns.TRUNCATEDS, truncateds),
            ):
                self.add_n_batch_items(batch, column, items, length + 1, sa_episode)
        shared_data["_added_loss_mask_for_valid_episode_ts"] = True
        return batch
