"""The Oracle's action distribution: a Beta on the turn, so the played policy is the trained one.

RLlib's default diagonal Gaussian is unbounded, and the pursuit action is a Box [0, 1]
(RLlib's normalised [−1, 1]). Sampled actions outside the Box are clipped, and with an
entropy bonus the Gaussian's std grows without bound (median 536 after 8 generations,
98 % of sampled actions clipped): the learner trains as a random bang-bang controller
while the export plays its mean, which nothing trained. A Beta has the Box as its support:
nothing is clipped, its entropy is bounded above (by the uniform's), and its
deterministic action, the mean, is the centre of what is sampled.

`BetaTurn` lives on RLlib's normalised [−1, 1] (RLlib unsquashes to the Box); its two
inputs per action dimension map to concentrations softplus(x) + 1 ≥ 1, so the density is
unimodal and finite at the bounds. `hola_ray.policies.learned` plays the same mean in
plain torch (`MLPPolicy.mean`, through the same `beta_concentrations`).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import torch
from ray.rllib.core.distribution.torch.torch_distribution import (
    TorchDeterministic,
    TorchDistribution,
)

from hola_ray.policies.learned import beta_concentrations

_EPS = 1e-6
"""Samples and evaluated actions stay this far inside (0, 1): a float32 Beta sample can
round to exactly 0 or 1, where the log-density is infinite."""


class BetaTurn(TorchDistribution):
    """Independent Betas on [−1, 1] per action dimension: a = 2·x − 1, x ~ Beta(c1, c0)."""

    def __init__(self, concentration1: torch.Tensor, concentration0: torch.Tensor):
        self.concentration1 = concentration1
        self.concentration0 = concentration0
        super().__init__(concentration1=concentration1, concentration0=concentration0)

    def _get_torch_distribution(self, concentration1, concentration0):
        return torch.distributions.Beta(concentration1, concentration0, validate_args=False)

    def logp(self, value: torch.Tensor, **kwargs) -> torch.Tensor:
        x = ((value + 1.0) / 2.0).clamp(_EPS, 1.0 - _EPS)
        # the density of a = 2x − 1 is p_x(x) / 2
        return (self._dist.log_prob(x) - math.log(2.0)).sum(-1)

    def entropy(self) -> torch.Tensor:
        return (self._dist.entropy() + math.log(2.0)).sum(-1)

    def kl(self, other: BetaTurn) -> torch.Tensor:
        return torch.distributions.kl.kl_divergence(self._dist, other._dist).sum(-1)

    def sample(self, *, sample_shape=None) -> torch.Tensor:
        x = self._dist.sample(sample_shape if sample_shape is not None else torch.Size())
        return 2.0 * x.clamp(_EPS, 1.0 - _EPS) - 1.0

    def rsample(self, *, sample_shape=None) -> torch.Tensor:
        x = self._dist.rsample(sample_shape if sample_shape is not None else torch.Size())
        return 2.0 * x.clamp(_EPS, 1.0 - _EPS) - 1.0

    @property
    def mean(self) -> torch.Tensor:
        """The deterministic action on [−1, 1]."""
        return 2.0 * self._dist.mean - 1.0

    @property
    def stddev(self) -> torch.Tensor:
        """Standard deviation on [−1, 1] (twice the Beta's)."""
        return 2.0 * self._dist.stddev

    @staticmethod
    def required_input_dim(space: gym.Space, **kwargs) -> int:
        assert isinstance(space, gym.spaces.Box)
        return int(np.prod(space.shape, dtype=np.int32) * 2)

    @classmethod
    def from_logits(cls, logits: torch.Tensor, **kwargs) -> BetaTurn:
        c1, c0 = beta_concentrations(logits)
        return cls(concentration1=c1, concentration0=c0)

    def to_deterministic(self) -> TorchDeterministic:
        return TorchDeterministic(loc=self.mean)
