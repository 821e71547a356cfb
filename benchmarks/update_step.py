"""The Oracle's PPO update against the machine's limit: its arithmetic rate beside a large
matmul's, for each way the lean update computes its loss, and a bare-torch step.

    python benchmarks/update_step.py [--config configs/sp.yaml] [--repeats 6]
                                     [--paths module,eager,compiled] [--set oracle.x=y ...]

One Oracle of the config (self-play: the learner in every seat) trains one iteration at a
time (one train batch, its epochs of minibatches, no sampling ahead); its learner switches
between the loss paths (`OracleLearner.set_loss_path`) repeat by repeat, interleaved, so
every path updates on batches of the same kind on the same threads:
- `module`: RLlib's forward pass, then the lean loss (the update before `oracle.compile`);
- `eager`: the fused loss function (`hola_ray/oracle/fused.py`) uncompiled (oracle.compile
  false);
- `compiled`: the same function compiled (oracle.compile true).
Each reports the whole update (`update_s`: the learner pipeline, GAE, the loop) and the
minibatch steps alone (`step_s`: forward, loss, backward, clip, Adam) per gradient step.
Between repeats a bare-torch step of the same shape runs as many times (eager torch:
actor, critic, Beta head, clipped losses, global-norm clip, fused Adam).

The arithmetic rate counts the networks' FLOPs per gradient step (forward 2·rows·weights;
backward the weight gradients, 2·rows·weights, and the input gradients of every layer but
the first; Adam 12 per parameter) over the measured time; the limit is a 1024³ float32
matmul's rate measured in the same run, on the machine's threads and on the learner's.
Before any timing, one fixed minibatch's loss and gradients are computed by every path
from the same weights: their largest differences from `module`'s are printed (the fused
loss changes no result: the test holds them under 1e-5). Prints one JSON line per repeat
and a summary line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path

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


def network_flops(config, obs_dim: int) -> float:
    """FLOPs of one gradient step: the actor's and the critic's forward and backward passes
    on a minibatch, and Adam over their parameters."""
    o = config.oracle
    features = o.model_features(config.env) or {"indices": []}
    inputs = obs_dim + len(features["indices"])
    total = 0.0
    for out in (2, 1):  # the Beta head's two inputs, the value
        sizes = [inputs, *o.hidden, out]
        layers = [a * b for a, b in zip(sizes[:-1], sizes[1:], strict=True)]
        params = sum(layers) + sum(sizes[1:])
        total += 2 * o.minibatch * sum(layers)  # forward
        total += 2 * o.minibatch * sum(layers) + 2 * o.minibatch * sum(layers[1:])  # backward
        total += 12 * params  # Adam
    return total


def matmul_rate(threads: int, n: int = 1024, repeats: int = 20) -> float:
    """FLOP/s of an n³ float32 matmul on `threads` torch threads (best of `repeats`)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        a, b = torch.randn(n, n), torch.randn(n, n)
        for _ in range(3):
            a @ b
        best = math.inf
        for _ in range(repeats):
            start = time.perf_counter()
            a @ b
            best = min(best, time.perf_counter() - start)
        return 2 * n**3 / best
    finally:
        torch.set_num_threads(before)


def learner_counts(oracle) -> tuple[float, float, int]:
    (row,) = [
        r.get()
        for r in oracle.algo.learner_group.foreach_learner(
            lambda lr: (lr.update_s, lr.step_s, lr.gradient_steps)
        )
    ]
    return row


def set_path(oracle, path: str) -> None:
    oracle.algo.learner_group.foreach_learner(lambda lr: lr.set_loss_path(path))


def loss_differences(oracle, paths: list[str], obs_dim: int) -> dict[str, dict[str, float]]:
    """Each path's loss and gradients on one fixed minibatch from the same weights, as the
    largest absolute differences from the `module` path's."""

    def run(learner) -> dict[str, dict[str, float]]:
        import torch

        from hola_ray.oracle import LEARNER

        gen = torch.Generator().manual_seed(0)
        rows = learner.config.minibatch_size
        batch = {
            LEARNER: {
                "obs": torch.rand(rows, obs_dim, generator=gen) * 2 - 1,
                "actions": torch.rand(rows, 1, generator=gen) * 1.8 - 0.9,
                "action_logp": torch.randn(rows, generator=gen) * 0.3,
                "advantages": torch.randn(rows, generator=gen) * 2,
                "value_targets": torch.randn(rows, generator=gen) * 5,
            }
        }
        module = learner.module[LEARNER]
        config = learner.config.get_config_for_module(LEARNER)
        out = {}
        for path in ["module", *[p for p in paths if p != "module"]]:
            learner.set_loss_path(path)
            module.zero_grad(set_to_none=True)
            fused = learner._fused_losses(batch)
            if fused is None:
                fwd = module.forward_train(batch[LEARNER])
                loss = learner.compute_loss_for_module(
                    module_id=LEARNER, config=config, batch=batch[LEARNER], fwd_out=fwd
                )
            else:
                loss, _ = fused[LEARNER](batch[LEARNER], config, 0.0)
            loss.backward()
            grads = [p.grad.clone() for p in module.parameters() if p.grad is not None]
            out[path] = (float(loss), grads)
        module.zero_grad(set_to_none=True)
        loss0, grads0 = out["module"]
        return {
            path: {
                "loss": abs(loss - loss0),
                "loss_rel": abs(loss - loss0) / max(abs(loss0), 1e-12),
                "gradient": max(
                    float((g - g0).abs().max()) for g, g0 in zip(grads, grads0, strict=True)
                ),
            }
            for path, (loss, grads) in out.items()
        }

    (row,) = oracle.algo.learner_group.foreach_learner(run)
    return row.get() if hasattr(row, "get") else row


def interval(values: list[float]) -> list[float]:
    half = T975[min(len(values) - 1, len(T975) - 1)] * statistics.stdev(values)
    half /= len(values) ** 0.5
    return [round(statistics.mean(values) - half, 3), round(statistics.mean(values) + half, 3)]


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "sp.yaml")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    parser.add_argument("--repeats", type=int, default=6, help="iterations per path")
    parser.add_argument("--paths", default="module,eager,compiled")
    args = parser.parse_args(argv)
    paths = args.paths.split(",")

    import torch

    from hola_ray.commands.run import read_config
    from hola_ray.config.oracle import Seating
    from hola_ray.oracle import Oracle
    from hola_ray.process import join_or_init_ray

    config = read_config(args.config, args.sets)
    obs_dim = config.env.layout.dim
    flops = network_flops(config, obs_dim)
    started = join_or_init_ray("update_step", num_cpus=2)
    oracle = Oracle(config.env, config.oracle, Seating(), config.seed)
    batch = config.oracle.train_batch
    rows: list[dict] = []
    try:
        differences = loss_differences(oracle, paths, obs_dim)
        print(json.dumps({"loss_differences_from_module": differences}), flush=True)
        for path in paths:  # warm-up: each path's first update (the compile among them)
            set_path(oracle, path)
            oracle.train(batch, progress=False)
        step = bare_step(config, obs_dim)
        for _ in range(3):
            step()
        for repeat in range(args.repeats):
            for path in paths:
                set_path(oracle, path)
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
                        "path": path,
                        "gradient_steps": steps,
                        "torch_threads": torch.get_num_threads(),
                        "update_ms_per_step": round(1e3 * update_s / steps, 3),
                        "step_ms": round(1e3 * step_s / steps, 3),
                        "bare_ms": round(1e3 * bare_s, 3),
                    }
                )
                print(json.dumps(rows[-1]), flush=True)
    finally:
        oracle.stop()
        if started:
            import ray

            ray.shutdown()
    threads = {r["torch_threads"] for r in rows}.pop()
    machine = os.cpu_count() or 1
    limit = {"machine": matmul_rate(machine), "learner": matmul_rate(threads)}
    summary: dict = {
        "config": str(args.config),
        "sets": args.sets,
        "minibatch": config.oracle.minibatch,
        "hidden": list(config.oracle.hidden),
        "network_mflop_per_step": round(flops / 1e6, 2),
        "matmul_gflops": {
            f"{machine}_threads (the machine)": round(limit["machine"] / 1e9, 1),
            f"{threads}_threads (the learner's)": round(limit["learner"] / 1e9, 1),
        },
        "loss_differences_from_module": differences,
        "paths": {},
    }
    for path in paths + ["bare"]:
        mine = [r for r in rows if r["path"] == path] if path != "bare" else rows
        key = "bare_ms" if path == "bare" else "update_ms_per_step"
        update_ms = statistics.median(r[key] for r in mine)
        entry = {"update_ms_per_step": update_ms}
        if path != "bare":
            entry["step_ms"] = statistics.median(r["step_ms"] for r in mine)
        rate = flops / (update_ms / 1e3)
        entry["update_gflops"] = round(rate / 1e9, 2)
        entry["of_machine_matmul"] = round(rate / limit["machine"], 3)
        entry["of_learner_threads_matmul"] = round(rate / limit["learner"], 3)
        summary["paths"][path] = entry
    if "module" in paths:
        for path in paths:
            ratios = [
                m["update_ms_per_step"] / r["update_ms_per_step"]
                for m, r in zip(
                    [x for x in rows if x["path"] == "module"],
                    [x for x in rows if x["path"] == path],
                    strict=True,
                )
            ]
            summary["paths"][path]["rate_over_module"] = {
                "mean": round(statistics.mean(ratios), 3),
                "95": interval(ratios) if len(ratios) > 1 else None,
            }
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
