"""A frozen population member inside the Oracle: it plays its deterministic action.

RLlib samples every module's action from its Gaussian while exploring. A population
member is not being trained, and the Grapher and the zero-shot evaluation play it
deterministically (its Gaussian's mean, rescaled to the Box), so the learner would
otherwise train with noisier teammates than the ones it is measured with: early members
keep a wide Gaussian (std ≈ 1 in RLlib's [−1, 1] action space) and, sampled, collide in
nearly every episode. `FrozenPartnerModule` makes exploration return the mean, so a
partner in the Oracle acts exactly as it does everywhere else.
"""

from __future__ import annotations

from typing import Any

import torch
from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
from ray.rllib.core.columns import Columns


class FrozenPartnerModule(DefaultPPOTorchRLModule):
    """RLlib's default PPO module whose exploration forward pass acts deterministically."""

    def _forward_exploration(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        out = self._forward_inference(batch, **kwargs)
        dist_cls = self.get_inference_action_dist_cls()
        actions = dist_cls.from_logits(out[Columns.ACTION_DIST_INPUTS]).to_deterministic().sample()
        out[Columns.ACTIONS] = actions
        # Never trained on: PPO's loss skips frozen modules. A point mass has no density.
        out[Columns.ACTION_LOGP] = torch.zeros(actions.shape[:-1], device=actions.device)
        return out
