"""The Oracle's RLlib modules: RLlib's default PPO actor-critic with the project's action
distribution and proximity features, and the frozen-partner variant that acts by its mean.

`PursuitCatalog` builds RLlib's default PPO encoder and heads with `BetaTurn` (or RLlib's
Gaussian) as the action distribution and, when the model config names proximity features,
an encoder input widened by them. `PursuitPPOModule` appends those features
(`hola_ray.policies.learned.proximity_features`) to the observation before every forward
pass, so `MLPPolicy` replays the module exactly from its export.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from ray.rllib.algorithms.ppo.ppo_catalog import PPOCatalog
from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
from ray.rllib.core.columns import Columns
from ray.rllib.core.distribution.torch.torch_distribution import TorchDiagGaussian

from hola_ray.oracle.distribution import BetaTurn
from hola_ray.policies.learned import proximity_features

DISTRIBUTION_CLASSES = {"beta": BetaTurn, "gaussian": TorchDiagGaussian}
"""oracle.action_dist → RLlib distribution class."""


class PursuitCatalog(PPOCatalog):
    """RLlib's PPO catalog with the model config's `action_dist` and `proximity` features.

    Model config keys beyond RLlib's: `action_dist` (beta or gaussian) and `proximity`
    ({"indices": [...], "gain": g}, or absent): the encoders take the observation with one
    feature per index appended.
    """

    def __init__(self, observation_space: gym.Space, action_space: gym.Space, model_config_dict):
        extra = len((model_config_dict.get("proximity") or {}).get("indices", ()))
        if extra:
            (dim,) = observation_space.shape
            observation_space = gym.spaces.Box(-np.inf, np.inf, (dim + extra,), np.float32)
        super().__init__(observation_space, action_space, model_config_dict)

    def get_action_dist_cls(self, framework: str):
        if framework != "torch":
            raise ValueError(f"the pursuit modules are torch modules, not {framework}")
        return DISTRIBUTION_CLASSES[self._model_config_dict.get("action_dist", "beta")]


class PursuitPPOModule(DefaultPPOTorchRLModule):
    """RLlib's default PPO module reading the observation with proximity features appended."""

    def setup(self) -> None:
        super().setup()
        proximity = self.model_config.get("proximity") or {}
        self._feature_indices = [int(i) for i in proximity.get("indices", ())]
        self._feature_gain = float(proximity.get("gain", 0.0))

    def _with_features(self, batch: dict[str, Any]) -> dict[str, Any]:
        if not self._feature_indices:
            return batch
        obs = proximity_features(batch[Columns.OBS], self._feature_indices, self._feature_gain)
        return {**batch, Columns.OBS: obs}

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        return super()._forward(self._with_features(batch), **kwargs)

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        return super()._forward_train(self._with_features(batch), **kwargs)

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        if embeddings is None:
            batch = self._with_features(batch)
        return super().compute_values(batch, embeddings)


class FrozenPartnerModule(PursuitPPOModule):
    """A population member inside the Oracle: exploration returns its deterministic action.

    RLlib samples every module's action while exploring. A member is not being trained,
    and the Grapher and the zero-shot evaluation play it deterministically, so sampled it
    would make the learner train with noisier teammates than the ones it is measured with.
    """

    def _forward_exploration(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        out = self._forward_inference(batch, **kwargs)
        dist_cls = self.get_inference_action_dist_cls()
        actions = dist_cls.from_logits(out[Columns.ACTION_DIST_INPUTS]).to_deterministic().sample()
        out[Columns.ACTIONS] = actions
        # Never trained on: PPO's loss skips frozen modules. A point mass has no density.
        out[Columns.ACTION_LOGP] = torch.zeros(actions.shape[:-1], device=actions.device)
        return out
