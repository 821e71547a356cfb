"""The lean update's PPO loss as one compiled function of the module's weights.

RLlib's module runs its forward pass layer by layer through its encoder, heads and
distribution classes, and autograd records every small op: at the Oracle's sizes (two
64 × 64 tanh networks, minibatches of 1,024) each op costs more in dispatch than in
arithmetic. `FusedLoss` reads the same actor and critic (the module's own `nn.Linear`
weights, so the optimizer, the exports and RLlib's weight pushes see nothing new) and
computes `OracleLearner.compute_loss_for_module`'s loss in one function that
`torch.compile` turns into a few fused kernels forward and one backward. Same inputs, the
same formula, op for op; what differs is float rounding within fused kernels (tested to
1e-5 against the lean loss, with its gradients and logged figures).

Only the networks the Oracle builds take this path: tanh MLP encoders, linear heads, the
Beta turn (`hola_ray.oracle.distribution.BetaTurn`), no KL penalty. `FusedLoss.of` returns
None for anything else, and the learner keeps RLlib's forward pass for it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing

from hola_ray.oracle.distribution import _EPS, BetaTurn
from hola_ray.policies.learned import BETA_MAX_CONCENTRATION

_LOG2 = math.log(2.0)


def _mlp_params(*nets: torch.nn.Module) -> list[torch.nn.Parameter] | None:
    """[W0, b0, W1, b1, …] of nets that are Linear, Tanh, Linear, Tanh, …, Linear in
    sequence (the last layer linear), or None when they are anything else."""
    layers = [m for net in nets for m in net.children()]
    params: list[torch.nn.Parameter] = []
    for i, layer in enumerate(layers):
        want = torch.nn.Linear if i % 2 == 0 else torch.nn.Tanh
        if type(layer) is not want:
            return None
        if want is torch.nn.Linear:
            if layer.bias is None:
                return None
            params += [layer.weight, layer.bias]
    return params if len(layers) % 2 == 1 else None


_TANH_CLAMP = 7.90531110763549805
_TANH_NUMERATOR = (  # odd: x·(α1 + α3·x² + … + α13·x¹²)
    4.89352455891786e-03,
    6.37261928875436e-04,
    1.48572235717979e-05,
    5.12229709037114e-08,
    -8.60467152213735e-11,
    2.00018790482477e-13,
    -2.76076847742355e-16,
)
_TANH_DENOMINATOR = (  # even: β0 + β2·x² + β4·x⁴ + β6·x⁶
    4.89352518554385e-03,
    2.26843463243900e-03,
    1.18534705686654e-04,
    1.19825839466702e-06,
)


class _RationalTanh(torch.autograd.Function):
    """tanh(x) as Eigen's [13/6] rational function (within 4e-7 of torch.tanh on all of R;
    x itself below 4e-4), its gradient (1 − y²)·g. Only multiply-adds and one division, so
    the inductor vectorises it; its exp-based tanh on this CPU took the largest part of the
    compiled forward pass."""

    @staticmethod
    def forward(ctx, x: torch.Tensor) -> torch.Tensor:
        c = x.clamp(-_TANH_CLAMP, _TANH_CLAMP)
        c2 = c * c
        p = torch.full_like(c, _TANH_NUMERATOR[-1])
        for a in reversed(_TANH_NUMERATOR[:-1]):
            p = p * c2 + a
        q = torch.full_like(c, _TANH_DENOMINATOR[-1])
        for b in reversed(_TANH_DENOMINATOR[:-1]):
            q = q * c2 + b
        y = torch.where(x.abs() < 4e-4, x, c * p / q)
        ctx.save_for_backward(y)
        return y

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        (y,) = ctx.saved_tensors
        return grad * (1.0 - y * y)


def _fast_tanh(x: torch.Tensor) -> torch.Tensor:
    return _RationalTanh.apply(x)


def _mlp(params: Sequence[torch.Tensor], x: torch.Tensor, tanh: Callable) -> torch.Tensor:
    """tanh between the linear layers, none after the last (RLlib's encoder then head)."""
    last = len(params) - 2
    for i in range(0, last, 2):
        x = tanh(torch.nn.functional.linear(x, params[i], params[i + 1]))
    return torch.nn.functional.linear(x, params[last], params[last + 1])


def ppo_loss(
    actor: Sequence[torch.Tensor],
    critic: Sequence[torch.Tensor],
    obs: torch.Tensor,  # [rows, obs_dim]
    actions: torch.Tensor,  # [rows, 1], on RLlib's normalised [−1, 1]
    logp_old: torch.Tensor,  # [rows]
    advantages: torch.Tensor,  # [rows]
    targets: torch.Tensor,  # [rows]
    mask: torch.Tensor | None,  # [rows] bool, or None: every row counts
    coefs: torch.Tensor,  # [4]: clip, vf_clip, vf_coef, entropy_coef
    features: tuple[tuple[int, ...], float],  # proximity feature indices and gain
    entropy: bool,
    tanh: Callable = torch.tanh,
) -> tuple[torch.Tensor, ...]:
    """The lean PPO loss (`OracleLearner.compute_loss_for_module`) and what its logged
    figures read: (total, surrogate, vf_loss, vf_clipped, values, logits)."""
    indices, gain = features
    if indices:  # hola_ray.policies.learned.proximity_features
        obs = torch.cat([obs, torch.exp(-gain * obs[..., list(indices)])], dim=-1)
    logits = _mlp(actor, obs, tanh)
    # BetaTurn.from_logits: concentrations softplus(x) + 1, capped
    c = (torch.nn.functional.softplus(logits) + 1.0).clamp(max=BETA_MAX_CONCENTRATION)
    c1, c0 = c.chunk(2, dim=-1)
    conc = torch.stack([c1, c0], -1)  # torch's Beta is a Dirichlet on (x, 1 − x)
    x = ((actions + 1.0) / 2.0).clamp(_EPS, 1.0 - _EPS)
    heads_tails = torch.stack([x, 1.0 - x], -1)
    log_density = (
        torch.xlogy(conc - 1.0, heads_tails).sum(-1)
        + torch.lgamma(conc.sum(-1))
        - torch.lgamma(conc).sum(-1)
    )
    logp = (log_density - _LOG2).sum(-1)
    ratio = torch.exp(logp - logp_old)
    clip, vf_clip, vf_coef, entropy_coef = coefs.unbind()
    surrogate = torch.min(advantages * ratio, advantages * torch.clamp(ratio, 1 - clip, 1 + clip))
    values = _mlp(critic, obs, tanh).squeeze(-1)
    vf_loss = torch.pow(values - targets, 2.0)
    vf_clipped = torch.clamp(vf_loss, min=torch.zeros_like(vf_clip), max=vf_clip)
    per_row = -surrogate + vf_coef * vf_clipped
    if entropy:  # Dirichlet.entropy of the two concentrations, + log 2 for a = 2x − 1
        a0 = conc.sum(-1)
        h = (
            torch.lgamma(conc).sum(-1)
            - torch.lgamma(a0)
            - (2 - a0) * torch.digamma(a0)
            - ((conc - 1.0) * torch.digamma(conc)).sum(-1)
        )
        per_row = per_row - entropy_coef * (h + _LOG2).sum(-1)
    if mask is None:
        total = torch.mean(per_row)
    else:
        total = torch.sum(torch.where(mask, per_row, 0.0)) / torch.sum(mask)
    return total, surrogate, vf_loss, vf_clipped, values, logits


_COMPILED: dict[bool, Callable] = {}
"""compile → the loss function (one per process: torch.compile caches its graphs per input
shapes, so every module of one size shares them)"""


def _loss_function(compile: bool) -> Callable:
    if compile not in _COMPILED:
        _COMPILED[compile] = (
            torch.compile(
                functools.partial(ppo_loss, tanh=_fast_tanh), dynamic=False, fullgraph=True
            )
            if compile
            else ppo_loss
        )
    return _COMPILED[compile]


class FusedLoss:
    """One trained module's PPO loss from its own weights, compiled or eager."""

    def __init__(
        self,
        actor: list[torch.nn.Parameter],
        critic: list[torch.nn.Parameter],
        features: tuple[tuple[int, ...], float],
        compile: bool = True,
    ):
        self.actor, self.critic, self.features = actor, critic, features
        self.loss = _loss_function(compile)

    @classmethod
    def of(cls, module: torch.nn.Module, config, compile: bool = True) -> FusedLoss | None:
        """The fused loss of an Oracle module (`PursuitPPOModule`) trained under `config`
        (RLlib's per-module PPO config), or None where it is not the plain network this
        function computes (another distribution, a shared encoder, the KL penalty)."""
        if config.use_kl_loss or module.get_train_action_dist_cls() is not BetaTurn:
            return None
        encoder = module.encoder
        try:
            actor = _mlp_params(encoder.actor_encoder.net.mlp, module.pi.net.mlp)
            critic = _mlp_params(encoder.critic_encoder.net.mlp, module.vf.net.mlp)
        except AttributeError:  # a shared encoder, or not RLlib's default MLP module
            return None
        if actor is None or critic is None:
            return None
        features = (tuple(module._feature_indices), float(module._feature_gain))
        return cls(actor, critic, features, compile)

    def __call__(
        self, batch: Mapping[str, torch.Tensor], config, entropy_coeff: float
    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """(the loss, its detached terms for the logged figures) on one minibatch."""
        coefs = torch.tensor(
            [config.clip_param, config.vf_clip_param, config.vf_loss_coeff, entropy_coeff],
            dtype=torch.float32,
        )
        total, surrogate, vf_loss, vf_clipped, values, logits = self.loss(
            self.actor,
            self.critic,
            batch[Columns.OBS],
            batch[Columns.ACTIONS],
            batch[Columns.ACTION_LOGP],
            batch[Postprocessing.ADVANTAGES],
            batch[Postprocessing.VALUE_TARGETS],
            batch.get(Columns.LOSS_MASK),
            coefs,
            self.features,
            bool(entropy_coeff),
        )
        terms = {
            "surrogate": surrogate.detach(),
            "vf_loss": vf_loss.detach(),
            "vf_clipped": vf_clipped.detach(),
            "values": values.detach(),
            "logits": logits.detach(),
        }
        return total, terms
