"""One PPO gradient step of the Oracle's learner against the same step in bare torch.

    python benchmarks/update_step.py [--config configs/sp.yaml] [--repeats 8]
                                     [--set oracle.x=y ...]

The Oracle of the config (self-play: the learner in every seat) trains one iteration at a
time (one train batch, its epochs of minibatches, no sampling ahead), and the learner
reports what the update cost: the whole update (`update_s`: the learner pipeline, GAE,
RLlib's loop) and the minibatch steps alone (`step_s`: forward pass, loss, backward pass,
clip, Adam), per gradient step. Between two of them, in the same process and on the same
torch threads, a bare-torch step of the same shape runs as many times: the same actor
and critic (the module's layer sizes, tanh), the same minibatch, the proximity features,
the Beta head, the clipped surrogate, the clipped value loss with its coefficient, the
global-norm clip and a fused Adam. Prints one JSON line per repeat and a summary line:
the medians, and lean ÷ bare with a 95 % t-interval over the repeats.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
T975 = (float("nan"), 12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228)


def bare_step(config, obs_dim: int):
    """A function running one bare-torch PPO step of the config's shape (its own Adam)."""
    import torch

    from hola_ray.policies.learned import beta_concentrations, proximity_features

    o, env = config.oracle, config.env
    features = o.model_features(env) or {"indices": [], "gain": 0.0}
    rows = o.minibatch

    def mlp(out: int) -> torch.nn.Sequential:
        layers, width = [], obs_dim + len(features["indices"])
        for h in o.hidden:
            layers += [torch.nn.Linear(width, h), torch.nn.Tanh()]
            width = h
        return torch.nn.Sequential(*layers, torch.nn.Linear(width, out))

    torch.manual_seed(0)
    actor, critic = mlp(2), mlp(1)
    params = [*actor.parameters(), *critic.parameters()]
    optim = torch.optim.Adam(params, lr=o.lr, fused=True)
    gen = torch.Generator().manual_seed(0)
    obs_raw = torch.rand(rows, obs_dim, generator=gen) * 2 - 1
    actions = torch.rand(rows, 1, generator=gen) * 1.96 - 0.98
    old_logp = torch.full((rows,), -0.5)
    advantages = torch.randn(rows, generator=gen)
    targets = torch.randn(rows, generator=gen)

    def step() -> None:
        obs = proximity_features(obs_raw, features["indices"], features["gain"])
        c1, c0 = beta_concentrations(actor(obs))
        x = ((actions + 1.0) / 2.0).clamp(1e-6, 1 - 1e-6)
        dist = torch.distributions.Beta(c1, c0, validate_args=False)
        logp = (dist.log_prob(x) - math.log(2.0)).sum(-1)
        ratio = torch.exp(logp - old_logp)
        surrogate = torch.min(
            advantages * ratio, advantages * torch.clamp(ratio, 1 - o.clip, 1 + o.clip)
        )
        value = critic(obs).squeeze(-1)
        vf_loss = torch.clamp((value - targets) ** 2, 0, o.vf_clip)
        per_row = -surrogate + o.vf_coef * vf_loss
        if o.entropy_coef:
            per_row = per_row - o.entropy_coef * dist.entropy().sum(-1)
        loss = per_row.mean()
        optim.zero_grad(set_to_none=True)
        loss.backward()
        grads = [p.grad for p in params]
        norm = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads)))
        if o.grad_clip:
            torch._foreach_mul_(grads, min(1.0, o.grad_clip / max(norm.item() + 1e-6, o.grad_clip)))
        optim.step()

    return step


def learner_counts(oracle) -> tuple[float, float, int]:
    (row,) = [
        r.get()
        for r in oracle.algo.learner_group.foreach_learner(
            lambda lr: (lr.update_s, lr.step_s, lr.gradient_steps)
        )
    ]
    return row


def interval(values: list[float]) -> list[float]:
    half = T975[min(len(values) - 1, len(T975) - 1)] * statistics.stdev(values)
    half /= len(values) ** 0.5
    return [round(statistics.mean(values) - half, 3), round(statistics.mean(values) + half, 3)]


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "sp.yaml")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    parser.add_argument("--repeats", type=int, default=8)
    args = parser.parse_args(argv)

    import torch

    from hola_ray.env.layout import ObsLayout
    from hola_ray.oracle import Oracle
    from hola_ray.oracle.config import Seating
    from hola_ray.process import init_ray
    from hola_ray.run import read_config

    config = read_config(args.config, args.sets)
    init_ray("update_step", num_cpus=2)
    oracle = Oracle(config.env, config.oracle, Seating(), config.seed)
    batch = config.oracle.train_batch
    rows = []
    try:
        oracle.train(batch, progress=False)  # warm-up
        step = bare_step(config, ObsLayout.from_config(config.env).dim)
        for _ in range(3):
            step()
        for repeat in range(args.repeats):
            before = learner_counts(oracle)
            oracle.train(batch, progress=False)  # one iteration, nothing sampled ahead
            after = learner_counts(oracle)
            update_s, step_s, steps = (a - b for a, b in zip(after, before, strict=True))
            start = time.perf_counter()
            for _ in range(steps):
                step()
            bare_s = (time.perf_counter() - start) / steps
            rows.append(
                {
                    "repeat": repeat,
                    "gradient_steps": steps,
                    "torch_threads": torch.get_num_threads(),
                    "update_ms_per_step": round(1e3 * update_s / steps, 3),
                    "step_ms": round(1e3 * step_s / steps, 3),
                    "bare_ms": round(1e3 * bare_s, 3),
                    "update_over_bare": round(update_s / steps / bare_s, 3),
                    "step_over_bare": round(step_s / steps / bare_s, 3),
                }
            )
            print(json.dumps(rows[-1]), flush=True)
    finally:
        oracle.stop()
    summary = {
        "config": str(args.config),
        "sets": args.sets,
        "update": config.oracle.update,
        "minibatch": config.oracle.minibatch,
        "hidden": list(config.oracle.hidden),
    }
    for key in ("update_ms_per_step", "step_ms", "bare_ms"):
        summary[key] = statistics.median(r[key] for r in rows)
    for key in ("update_over_bare", "step_over_bare"):
        values = [r[key] for r in rows]
        summary[key] = {"mean": round(float(np.mean(values)), 3), "95": interval(values)}
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
