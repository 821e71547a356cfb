"""A learned pursuer in plain torch: the exported actor of an RLlib PPO module.

The export is a small dict saved with `torch.save`: the actor's linear layers, its
activation, its action distribution and the action bounds. `MLPPolicy` plays it without
Ray or RLlib, with the same arithmetic as RLlib's `forward_inference`, the distribution's
deterministic action and the env runner's action rescaling:

- `beta` (the Oracle's distribution, `hola_ray.oracle.distribution.BetaTurn`): the
  head's two outputs give concentrations c = softplus(x) + 1 and the action is the Beta's
  mean, 2·c1/(c1 + c0) − 1 in RLlib's normalised [−1, 1];
- `gaussian` (RLlib's default, exports of format 1): the head's first output, the mean.

The normalised action maps to the Box as low + (a + 1)·(high − low)/2, clipped.

An export may name proximity features (`proximity_features`): the actor then reads the
observation with exp(−gain·x) of the obstacle and teammate distance readings appended,
as the RLlib module did (`hola_ray.oracle.module`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from hola_ray import homes
from hola_ray.config.oracle import DISTRIBUTIONS, OracleConfig
from hola_ray.config.scenario import PursuitConfig
from hola_ray.policies.base import Policy

FORMAT = "hola_ray.mlp/2"
"""The version tag of the export dict."""

_FORMATS = {"hola_ray.mlp/1": "gaussian", FORMAT: None}
"""Readable export formats → the distribution they imply (None: the export names it)."""


_ACTIVATIONS = {"tanh": torch.tanh, "relu": torch.relu, "linear": lambda x: x}

# Where RLlib's default PPO module keeps the actor: a shared or a separate actor encoder,
# then the policy head (mean and log-std of a diagonal Gaussian).
_ENCODER_PREFIXES = ("encoder.actor_encoder.net.mlp.", "encoder.encoder.net.mlp.")
_HEAD_PREFIX = "pi.net.mlp."


BETA_MAX_CONCENTRATION = 500.0
"""The Beta's concentrations are capped here (its std then stays ≥ 0.03 in [−1, 1], a
1.4° turn), so its log-density, and PPO's probability ratio, stay finite."""


def proximity_features(obs: torch.Tensor, indices: Sequence[int], gain: float) -> torch.Tensor:
    """obs [..., D] → [..., D + len(indices)]: exp(−gain·obs[..., i]) appended for each i.

    A distance reading d/scale of 0.2 m and one of 0.3 m differ by only 0.02 in the raw
    observation, against a range of 2; exp(−d/ρ) (gain = scale/ρ) spreads the few tenths of
    a metre where collisions happen over most of [0, 1], so the network resolves them."""
    if not indices:
        return obs
    return torch.cat([obs, torch.exp(-gain * obs[..., list(indices)])], dim=-1)


def beta_concentrations(logits: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The Beta's (c1, c0) from a head's outputs [..., 2·d]: softplus(x) + 1, capped at
    `BETA_MAX_CONCENTRATION`; the first half of the outputs gives c1, the second c0."""
    c = (torch.nn.functional.softplus(logits) + 1.0).clamp(max=BETA_MAX_CONCENTRATION)
    c1, c0 = c.chunk(2, dim=-1)
    return c1, c0


def export_trained(
    oracle: OracleConfig, state: Mapping[str, Any], env: PursuitConfig
) -> dict[str, Any]:
    """The plain-torch export (`MLPPolicy`) of an RLlib module state trained under the
    Oracle config `oracle`, with the scenario it was trained in and the commit that trained
    it."""
    from hola_ray.provenance import commit_id

    export = export_from_rllib(
        state, activation="tanh", dist=oracle.action_dist, features=oracle.model_features(env)
    )
    return export | {"scenario": env.to_dict(), "commit": commit_id()}


def export_from_rllib(
    state: Mapping[str, Any],
    activation: str = "tanh",
    low: float = 0.0,
    high: float = 1.0,
    dist: str = "beta",
    features: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The export dict of an RLlib default PPO module's state (`get_state()` or learner weights).

    The encoder layers take `activation`; the head's hidden layers (if any) take it too and
    its last layer is linear and outputs the distribution's inputs (`dist`). The whole last
    layer is kept so the matmul, and its rounding, is RLlib's. `features`: the module's
    proximity features ({"indices": [...], "gain": g}), or None.
    """
    if activation not in _ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(_ACTIVATIONS)}, got {activation!r}")
    if dist not in DISTRIBUTIONS:
        raise ValueError(f"dist must be one of {DISTRIBUTIONS}, got {dist!r}")
    encoder = next((p for p in _ENCODER_PREFIXES if f"{p}0.weight" in state), None)
    if encoder is None:
        raise ValueError(
            "not an RLlib default PPO module state: no actor encoder under "
            f"{' or '.join(_ENCODER_PREFIXES)}; keys: {sorted(state)[:8]}"
        )
    layers = _linear_layers(state, encoder) + _linear_layers(state, _HEAD_PREFIX)
    out_dim = layers[-1][0].shape[0]
    if out_dim % 2:
        raise ValueError(f"the policy head must output two numbers per action, got {out_dim}")
    out: dict[str, Any] = {"features": dict(features)} if features else {}
    return out | {
        "format": FORMAT,
        "dist": dist,
        "weights": [torch.as_tensor(np.asarray(w, dtype=np.float32)) for w, _ in layers],
        "biases": [torch.as_tensor(np.asarray(b, dtype=np.float32)) for _, b in layers],
        "activation": activation,
        "low": float(low),
        "high": float(high),
    }


def random_export(
    obs_dim: int, hidden: Sequence[int] = (16,), seed: int = 0, bias_scale: float = 1.0
) -> dict[str, Any]:
    """A random tanh actor (obs → hidden … → the Beta's two inputs) in the export format:
    a stand-in learner for tests and examples."""
    gen = torch.Generator().manual_seed(seed)
    sizes = [obs_dim, *hidden, 2]
    shapes = [(o, i) for i, o in zip(sizes[:-1], sizes[1:], strict=True)]
    return {
        "format": FORMAT,
        "dist": "beta",
        "weights": [torch.randn(s, generator=gen) for s in shapes],
        "biases": [torch.randn(s[0], generator=gen) * bias_scale for s in shapes],
        "activation": "tanh",
        "low": 0.0,
        "high": 1.0,
    }


def _linear_layers(state: Mapping[str, Any], prefix: str) -> list[tuple[Any, Any]]:
    indices = sorted(
        int(key[len(prefix) :].split(".")[0])
        for key in state
        if key.startswith(prefix) and key.endswith(".weight")
    )
    return [(state[f"{prefix}{i}.weight"], state[f"{prefix}{i}.bias"]) for i in indices]


class MLPPolicy(Policy):
    """A deterministic pursuer from an export dict: its distribution's deterministic action.

    It plays a scenario whose observation holds as many pursuer and evader slots as the one
    it was trained in: the same team, or, trained on slots (`env.obs_pursuers`), any team
    up to them."""

    def __init__(self, config: PursuitConfig, export: Mapping[str, Any], name: str = "mlp"):
        super().__init__(config)
        fmt = export.get("format")
        if fmt not in _FORMATS:
            raise ValueError(f"not a {FORMAT} export (format {fmt!r})")
        self.dist = _FORMATS[fmt] or export.get("dist")
        if self.dist not in DISTRIBUTIONS:
            raise ValueError(f"export names no known distribution ({self.dist!r})")
        self.name = name
        self.weights = [torch.as_tensor(w, dtype=torch.float32) for w in export["weights"]]
        self.biases = [torch.as_tensor(b, dtype=torch.float32) for b in export["biases"]]
        self.activation = _ACTIVATIONS[export["activation"]]
        self.low, self.high = float(export["low"]), float(export["high"])
        features = export.get("features") or {}
        self.feature_indices = [int(i) for i in features.get("indices", ())]
        self.feature_gain = float(features.get("gain", 0.0))
        self.scenario = export.get("scenario")
        """the arena it was trained in (PursuitConfig.to_dict()), when the export says"""
        if self.scenario is not None:
            trained = (self.scenario["n_pursuers"], self.scenario["n_evaders"])
            slots = (
                self.scenario.get("obs_pursuers") or trained[0],
                self.scenario.get("obs_evaders") or trained[1],
            )
            if slots != (config.pursuer_slots, config.evader_slots):
                raise ValueError(
                    f"{name} was trained for {trained[0]} pursuers vs {trained[1]} evader(s); "
                    f"this scenario has {config.n_pursuers} vs {config.n_evaders}"
                    + (
                        f" (observed in {slots[0]} and {slots[1]} slots)"
                        if slots != trained
                        else ""
                    )
                )
        inputs = self.weights[0].shape[1] - len(self.feature_indices)
        if inputs not in (self.layout.dim, self.layout.base_dim):
            raise ValueError(
                f"{name} was trained on observations of size {inputs}, "
                f"this scenario has {self.layout.dim}"
            )
        self.inputs = inputs
        """the observation's first entries it reads: all of them, or, trained without the
        teammates' headings, those before them"""

    @classmethod
    def load(
        cls, config_or_path: PursuitConfig | str | Path, path: str | Path | None = None
    ) -> MLPPolicy:
        """Load an exported learner (`learner.pt`, a member checkpoint) from disk:
        `load(path)` plays it in the scenario it was trained in (the export carries it);
        `load(config, path)` in `config`'s, which must have the same team sizes."""
        if path is None:
            config, path = None, config_or_path
        else:
            config = config_or_path
        export = torch.load(Path(path), map_location="cpu", weights_only=True)
        if config is None:
            scenario = export.get("scenario") or manifest_scenario(path)
            if scenario is None:
                raise ValueError(
                    f"{path} does not say which scenario it was trained in (exported before "
                    "exports carried it, and no manifest beside it lists it): load it with "
                    "MLPPolicy.load(config, path)"
                )
            config = PursuitConfig.from_dict(scenario)
        return cls(config, export, name=Path(path).stem)

    @torch.no_grad()
    def logits(self, obs: np.ndarray | torch.Tensor) -> torch.Tensor:
        """The actor's outputs [N, 2]: the action distribution's inputs."""
        if isinstance(obs, np.ndarray) and not obs.flags.writeable:
            obs = obs.copy()  # torch cannot wrap a read-only array
        return self.forward_features(self.with_features(torch.as_tensor(obs, dtype=torch.float32)))

    def with_features(self, obs: np.ndarray | torch.Tensor) -> torch.Tensor:
        """The observations [N, D] with this actor's proximity features appended [N, D']
        (the entries it was trained on: without the teammates' headings if so)."""
        obs = torch.as_tensor(obs)[:, : self.inputs]
        return proximity_features(obs, self.feature_indices, self.feature_gain)

    @torch.no_grad()
    def forward_features(self, x: torch.Tensor) -> torch.Tensor:
        """`logits` of observations that already carry the proximity features [N, D']."""
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = torch.nn.functional.linear(x, w, b)
            if k < last:
                x = self.activation(x)
        return x

    @torch.no_grad()
    def mean(self, obs: np.ndarray | torch.Tensor) -> torch.Tensor:
        """The deterministic action [N] in RLlib's normalised [−1, 1] action space."""
        x = self.logits(obs)
        if self.dist == "gaussian":
            return x[:, 0]
        c1, c0 = beta_concentrations(x)
        return (2.0 * (c1 / (c1 + c0)) - 1.0)[:, 0]  # torch's Beta.mean, then the affine map

    @torch.no_grad()
    def spread(self, obs: np.ndarray | torch.Tensor, samples: int = 16) -> dict[str, float]:
        """How wide the trained (sampled) policy is on `obs`, in RLlib's [−1, 1] units.

        std_median: the median over observations of the distribution's standard deviation;
        clipped: the fraction of sampled actions that reach the Box's edges (the Gaussian's
        samples outside [−1, 1], which the env runner clips; the Beta's samples within
        0.01 of ±1, a turn of at least 99 % of the largest, which it never clips).
        """
        x = self.logits(obs)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(0)
            if self.dist == "gaussian":
                mean, std = x[:, 0], x[:, 1].clamp(-20.0, 20.0).exp()
                sampled = mean + std * torch.randn((samples, mean.shape[0]))
                clipped = (sampled.abs() >= 1.0).float().mean()
            else:
                c1, c0 = (c[:, 0] for c in beta_concentrations(x))
                beta = torch.distributions.Beta(c1, c0)
                std = 2.0 * beta.stddev
                sampled = 2.0 * beta.sample((samples,)) - 1.0
                clipped = (sampled.abs() >= 0.99).float().mean()
        return {"std_median": float(std.median()), "clipped": float(clipped)}

    def act(self, obs: np.ndarray) -> np.ndarray:
        return rescale_action(self.mean(self._check(obs)).numpy(), self.low, self.high)


class MLPStack:
    """Several `MLPPolicy`s of one layout as one batched forward pass.

    Layer l of every actor is stacked into one [K, out, in] tensor (the actors' tensors as
    they are when the stack is made); a step's rows are grouped by actor into a [K, G, in]
    batch, padded to the largest group G, and go through one `baddbmm` per layer. A batched
    float32 matmul may round the last bit differently from an actor's own; the actions are
    the same policies' means to within 1e-6."""

    def __init__(self, actors: Sequence[MLPPolicy]) -> None:
        if not actors or not MLPStack.compatible(actors):
            raise ValueError("an MLPStack holds one or more actors of one layout")
        first = actors[0]
        self.size = len(actors)
        self.dist, self.low, self.high = first.dist, first.low, first.high
        self.with_features = first.with_features  # the same features for every actor
        self.activation = first.activation
        depth = len(first.weights)
        self.weights = [torch.stack([a.weights[k] for a in actors]) for k in range(depth)]
        self.biases = [torch.stack([a.biases[k] for a in actors])[:, None] for k in range(depth)]

    @staticmethod
    def compatible(actors: Sequence[MLPPolicy]) -> bool:
        """Whether the actors share one layout (layers, activation, features, distribution
        and action bounds), so that one stack can play them all."""
        first = actors[0]
        return all(
            [w.shape for w in a.weights] == [w.shape for w in first.weights]
            and a.activation is first.activation
            and a.feature_indices == first.feature_indices
            and a.feature_gain == first.feature_gain
            and (a.dist, a.low, a.high) == (first.dist, first.low, first.high)
            for a in actors
        )

    @torch.no_grad()
    def logits(self, x: torch.Tensor, slot: np.ndarray) -> torch.Tensor:
        """Distribution inputs [N, out] of rows x [N, in] (features appended), row i played
        by actor slot[i].

        An actor with over twice the mean group's rows (the Grapher's candidate, in every
        hyperedge) has its rows cut into pieces of about the mean's size, each a group of
        its own with the actor's layers, so the padded batch is not mostly padding.
        """
        order = np.argsort(slot, kind="stable")
        grouped = slot[order]
        counts = np.bincount(grouped, minlength=self.size)
        mean = -(-grouped.size // max(int((counts > 0).sum()), 1))
        # groups per actor: one, or pieces of about the mean when it has over twice that
        pieces = np.where(counts > 2 * mean, -(-counts // max(mean, 1)), 1)
        per_piece = -(-counts // pieces)
        starts = np.cumsum(counts) - counts
        rank = np.arange(grouped.size) - starts[grouped]
        piece = (np.cumsum(pieces) - pieces)[grouped] + rank // per_piece[grouped]
        row = rank % per_piece[grouped]
        actor = torch.from_numpy(np.repeat(np.arange(self.size), pieces))
        k, r = torch.from_numpy(piece), torch.from_numpy(row)
        h = x.new_zeros((len(actor), int(per_piece.max()), x.shape[1]))
        h[k, r] = x[torch.from_numpy(order)]
        split = len(actor) > self.size
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            if split:
                w, b = w[actor], b[actor]
            h = torch.baddbmm(b, h, w.transpose(1, 2))
            if i < last:
                h = self.activation(h)
        out = torch.empty((grouped.size, h.shape[-1]), dtype=h.dtype)
        out[torch.from_numpy(order)] = h[k, r]
        return out

    @torch.no_grad()
    def act(self, obs: np.ndarray, slot: np.ndarray) -> np.ndarray:
        """Actions [N] in [low, high] of observations [N, D], row i played by actor slot[i]:
        each actor's deterministic action, as `MLPPolicy.act` gives it."""
        x = self.logits(self.with_features(torch.from_numpy(np.ascontiguousarray(obs))), slot)
        if self.dist == "gaussian":
            mean = x[:, 0]
        else:
            c1, c0 = beta_concentrations(x)
            mean = (2.0 * (c1 / (c1 + c0)) - 1.0)[:, 0]
        return rescale_action(mean.numpy(), self.low, self.high)


def rescale_action(action: np.ndarray, low: float = 0.0, high: float = 1.0) -> np.ndarray:
    """RLlib's unsquash of a normalised action in [−1, 1] to the Box [low, high], clipped.

    Done in float32 like RLlib's (the Box is float32), so both give the same bits.
    """
    low32, high32 = np.float32(low), np.float32(high)
    action = np.asarray(action, dtype=np.float32)
    scaled = low32 + (action + np.float32(1.0)) * (high32 - low32) / np.float32(2.0)
    return np.clip(scaled, low32, high32)


def manifest_scenario(file: str | Path) -> dict | None:
    """The scenario a pool member's or a shipped population member's file was trained in,
    from the manifest beside it (`pools/hot/ppo-1.pt`: pools/hot/manifest.json;
    `pools/populations/NAME/members/node_0001.pt`: that population's): its exports predate
    exports carrying it. None for a file no manifest lists."""
    file = Path(file).resolve()
    for folder in (file.parent, file.parent.parent):
        manifest = homes.manifest_or_none(folder)
        if manifest is None:
            continue
        relative = file.relative_to(folder).as_posix()
        for entry in (manifest.get("members") or {}).values():
            if not isinstance(entry, dict) or entry.get("file") != relative:
                continue
            env = (entry.get("config_values") or manifest.get("config_values") or {}).get("env")
            return dict(env) if env else None
    return None
