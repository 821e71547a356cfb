"""A learned pursuer in plain torch: the exported actor of an RLlib PPO module.

The export is a small dict saved with `torch.save`: the actor's linear layers, its
activation and the action bounds. `MLPPolicy` plays it without Ray or RLlib, with the
same arithmetic as RLlib's `forward_inference` followed by the env runner's action
rescaling: the Gaussian's mean lives in [−1, 1] and maps to the Box as
low + (mean + 1)·(high − low)/2, clipped to [low, high].
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from hola_ray.env.config import PursuitConfig
from hola_ray.policies.base import Policy

FORMAT = "hola_ray.mlp/1"
"""The version tag of the export dict."""

_ACTIVATIONS = {"tanh": torch.tanh, "relu": torch.relu, "linear": lambda x: x}

# Where RLlib's default PPO module keeps the actor: a shared or a separate actor encoder,
# then the policy head (mean and log-std of a diagonal Gaussian).
_ENCODER_PREFIXES = ("encoder.actor_encoder.net.mlp.", "encoder.encoder.net.mlp.")
_HEAD_PREFIX = "pi.net.mlp."


def export_from_rllib(
    state: Mapping[str, Any], activation: str = "tanh", low: float = 0.0, high: float = 1.0
) -> dict[str, Any]:
    """The export dict of an RLlib default PPO module's state (`get_state()` or learner weights).

    The encoder layers take `activation`; the head's hidden layers (if any) take it too and
    its last layer is linear and outputs the Gaussian's mean and log-std. The whole last
    layer is kept (not only the mean's row) so the matmul, and its rounding, is RLlib's.
    """
    if activation not in _ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(_ACTIVATIONS)}, got {activation!r}")
    encoder = next((p for p in _ENCODER_PREFIXES if f"{p}0.weight" in state), None)
    if encoder is None:
        raise ValueError(
            "not an RLlib default PPO module state: no actor encoder under "
            f"{' or '.join(_ENCODER_PREFIXES)}; keys: {sorted(state)[:8]}"
        )
    layers = _linear_layers(state, encoder) + _linear_layers(state, _HEAD_PREFIX)
    out_dim = layers[-1][0].shape[0]
    if out_dim % 2:
        raise ValueError(f"the policy head must output mean and log-std, got {out_dim} outputs")
    return {
        "format": FORMAT,
        "weights": [torch.as_tensor(np.asarray(w, dtype=np.float32)) for w, _ in layers],
        "biases": [torch.as_tensor(np.asarray(b, dtype=np.float32)) for _, b in layers],
        "activation": activation,
        "low": float(low),
        "high": float(high),
    }


def _linear_layers(state: Mapping[str, Any], prefix: str) -> list[tuple[Any, Any]]:
    indices = sorted(
        int(key[len(prefix) :].split(".")[0])
        for key in state
        if key.startswith(prefix) and key.endswith(".weight")
    )
    return [(state[f"{prefix}{i}.weight"], state[f"{prefix}{i}.bias"]) for i in indices]


class MLPPolicy(Policy):
    """A deterministic pursuer from an export dict: the rescaled Gaussian mean of its actor."""

    def __init__(self, config: PursuitConfig, export: Mapping[str, Any], name: str = "mlp"):
        super().__init__(config)
        if export.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} export (format {export.get('format')!r})")
        self.name = name
        self.weights = [torch.as_tensor(w, dtype=torch.float32) for w in export["weights"]]
        self.biases = [torch.as_tensor(b, dtype=torch.float32) for b in export["biases"]]
        self.activation = _ACTIVATIONS[export["activation"]]
        self.low, self.high = float(export["low"]), float(export["high"])
        if self.weights[0].shape[1] != self.layout.dim:
            raise ValueError(
                f"{name} was trained on observations of size {self.weights[0].shape[1]}, "
                f"this scenario has {self.layout.dim}"
            )

    @classmethod
    def load(cls, config: PursuitConfig, path: str | Path) -> MLPPolicy:
        """Load an exported learner (`learner.pt`, a member checkpoint) from disk."""
        export = torch.load(Path(path), map_location="cpu", weights_only=True)
        return cls(config, export, name=Path(path).stem)

    @torch.no_grad()
    def mean(self, obs: np.ndarray | torch.Tensor) -> torch.Tensor:
        """The actor's Gaussian mean [N] in RLlib's normalised [−1, 1] action space."""
        if isinstance(obs, np.ndarray) and not obs.flags.writeable:
            obs = obs.copy()  # torch cannot wrap a read-only array
        x = torch.as_tensor(obs, dtype=torch.float32)
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = torch.nn.functional.linear(x, w, b)
            if k < last:
                x = self.activation(x)
        return x[:, 0]

    def act(self, obs: np.ndarray) -> np.ndarray:
        return rescale_action(self.mean(self._check(obs)).numpy(), self.low, self.high)


def rescale_action(action: np.ndarray, low: float = 0.0, high: float = 1.0) -> np.ndarray:
    """RLlib's unsquash of a normalised action in [−1, 1] to the Box [low, high], clipped.

    Done in float32 like RLlib's (the Box is float32), so both give the same bits.
    """
    low32, high32 = np.float32(low), np.float32(high)
    action = np.asarray(action, dtype=np.float32)
    scaled = low32 + (action + np.float32(1.0)) * (high32 - low32) / np.float32(2.0)
    return np.clip(scaled, low32, high32)
