"""Speed of the training service's parts on this machine, each against a peer in the same run.

    python benchmarks/service_speed.py [--quick | --smoke]

1. Grapher: hyperedge-evaluation episodes/s with 1 and 2 workers (evaluation actors side
   by side, the hyperedges in two chunks) on the same hyperedges and seeds → the speedup
   (target ≥ 1.8× on 2 CPUs), next to the machine's own scaling from one busy process to
   two, measured in the same run.
2. Oracle: environment steps/s sampled (over the time of each iteration outside the PPO
   update, which the learner times itself) and overall (sampling + PPO update), with the
   default config's PPO and the paper's (batch 1024, minibatch 256, 20 epochs, 256×256)
   → the paper's 1e6-step oracle in minutes; each with the batched env runner
   (`oracle.sampler: batched`, the default) and RLlib's step-by-step PettingZoo path
   (`oracle.sampler: pettingzoo`), measured in the same run.
3. One generation of the default config end to end, broken into pre-train, oracle,
   grapher and coordinator wall time.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import ray
import torch

from hola_ray.clock import column
from hola_ray.commands.run import DEFAULT
from hola_ray.config.oracle import SAMPLERS
from hola_ray.methods.config import RunConfig
from hola_ray.policies.learned import FORMAT
from hola_ray.population.evaluators import EvaluatorPool
from hola_ray.population.grapher import evaluate_edges
from hola_ray.population.state import edge_seed
from hola_ray.process import join_or_init_ray


def random_export(obs_dim: int, hidden: tuple[int, ...], seed: int) -> dict:
    g = torch.Generator().manual_seed(seed)
    sizes = [obs_dim, *hidden, 2]
    shapes = list(itertools.pairwise(sizes))
    return {
        "format": FORMAT,
        "dist": "beta",
        "weights": [torch.randn(o, i, generator=g) / i**0.5 for i, o in shapes],
        "biases": [torch.zeros(o) for _, o in shapes],
        "activation": "tanh",
        "low": 0.0,
        "high": 1.0,
    }


SPIN = """
import sys, time
start = time.perf_counter()
total = 0
for i in range(int(sys.argv[1])):
    total += i * i
print(time.perf_counter() - start)
"""
"""A pure Python loop that prints its own time (its interpreter's start not counted)."""


def _spins(copies: int, n: int) -> float:
    """The slowest of `copies` loops of `n` run side by side, each in a bare interpreter
    (no import of this script, Ray or torch: a spawned pool's workers would import them)."""
    started = [
        subprocess.Popen([sys.executable, "-c", SPIN, str(n)], stdout=subprocess.PIPE, text=True)
        for _ in range(copies)
    ]
    return max(float(p.communicate()[0]) for p in started)


def machine_scaling(rounds: int, n: int = 20_000_000) -> float:
    """Throughput of two busy processes side by side over one alone (2.0 on two free
    cores), the median of `rounds` alternated measurements."""
    ones, twos = [], []
    for _ in range(rounds):
        ones.append(_spins(1, n))
        twos.append(_spins(2, n))
    return 2 * statistics.median(ones) / statistics.median(twos)


def grapher_speed(
    config: RunConfig, members: int, episodes: int, rounds: int, spin: int = 20_000_000
) -> dict[str, float]:
    """1 and 2 workers on the same hyperedges and seeds, alternated `rounds` times (this
    machine's two cores are shared and their speed drifts); medians are reported."""
    env = config.env
    exports = {n: random_export(env.obs_dim, config.oracle.hidden, n) for n in range(members)}
    edges = list(itertools.combinations(range(members), config.l))
    pools = {workers: EvaluatorPool(env, workers) for workers in (1, 2)}
    for pool in pools.values():  # each actor compiles the simulator as it starts
        ray.get([actor.ping.remote() for actor in pool.actors().values()])
    ref = ray.put(exports)
    rates: dict[int, list[float]] = {1: [], 2: []}
    steps_per_s: dict[int, list[float]] = {1: [], 2: []}
    weights = {}
    for _ in range(rounds):
        for workers in (1, 2):
            results, stats = evaluate_edges(
                edges,
                pools[workers],
                ref,
                episodes,
                lambda e: edge_seed(0, 0, e),
                2,
                progress=False,
            )
            weights[workers] = results
            rates[workers].append(stats.episodes_per_s)
            steps_per_s[workers].append(sum(r.length * r.episodes for r in results) / stats.wall_s)
    for pool in pools.values():
        pool.shutdown()
    assert weights[1] == weights[2], "the weights changed with the worker count"
    out = {}
    for workers in (1, 2):
        out[f"grapher_episodes_per_s_{workers}w"] = statistics.median(rates[workers])
        print(
            f"  grapher, {workers} worker(s): {len(edges)} hyperedges × {episodes} episodes, "
            f"median of {rounds}: {out[f'grapher_episodes_per_s_{workers}w']:.1f} episodes/s "
            f"({statistics.median(steps_per_s[workers]):,.0f} env steps/s; runs "
            + ", ".join(f"{r:.0f}" for r in rates[workers])
            + ")"
        )
    out["grapher_speedup_2w_over_1w"] = (
        out["grapher_episodes_per_s_2w"] / out["grapher_episodes_per_s_1w"]
    )
    out["machine_scaling_2p_over_1p"] = machine_scaling(rounds, spin)
    print(
        f"  → speedup 2 workers / 1 worker: {out['grapher_speedup_2w_over_1w']:.2f}× "
        f"(this machine now, a pure Python loop in 2 processes / 1, median of {rounds}: "
        f"{out['machine_scaling_2p_over_1p']:.2f}×)"
    )
    return out


def oracle_speed(config: RunConfig, label: str, steps: int, sampler: str) -> dict[str, float]:
    config = dataclasses.replace(config, oracle=dataclasses.replace(config.oracle, sampler=sampler))
    label = f"{label}_{sampler}"
    oracle = config.strategy.make_oracle(config)
    try:
        oracle.train(config.oracle.train_batch, progress=False)  # warm-up iteration
        s = oracle.train(steps, progress=False)
    finally:
        oracle.stop()
    minutes = 1e6 / s.env_steps_per_s / 60
    print(
        f"  oracle [{label}]: {s.env_steps:,} env steps in {s.wall_s:.1f}s: sampled "
        f"{s.sampled_steps_per_s:,.0f} steps/s (sampling {s.sample_s:.1f}s), overall "
        f"{s.env_steps_per_s:,.0f} steps/s (PPO update {s.learn_s:.1f}s) → 1e6 steps in "
        f"{minutes:.1f} min"
    )
    return {
        f"oracle_sampled_steps_per_s_{label}": s.sampled_steps_per_s,
        f"oracle_env_steps_per_s_{label}": s.env_steps_per_s,
        f"oracle_1e6_minutes_{label}": minutes,
    }


def generation_breakdown(config: RunConfig) -> dict[str, float]:
    from hola_ray.methods.trainer import Trainer

    with tempfile.TemporaryDirectory() as tmp:
        rows = Trainer(dataclasses.replace(config, generations=1), tmp, progress=False).fit()
    pre, gen = rows[0], rows[1]
    parts = {
        "pretrain_s": pre["pretrain_s"],
        "g0_grapher_s": pre["grapher_s"],
        "oracle_s": gen["oracle_s"],
        "grapher_s": gen["grapher_s"],
        "coordinator_s": gen[column("coordinator")] + gen["persist_s"],
    }
    print("  one generation: " + ", ".join(f"{k} {v:.1f}" for k, v in parts.items()))
    return parts


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller measurements")
    parser.add_argument(
        "--smoke", action="store_true", help="tiny sizes on the smoke config (the suite's run)"
    )
    args = parser.parse_args(argv)
    started = join_or_init_ray("service_speed", num_cpus=2)
    configs = Path(__file__).resolve().parents[1] / "configs"
    default = RunConfig.from_dict(DEFAULT)
    paper = RunConfig.from_yaml(configs / "paper.yaml")
    steps = 10_000 if args.quick else 40_000
    if args.smoke:  # every part runs; its figures mean nothing
        default = paper = RunConfig.from_yaml(configs / "smoke.yaml")
        steps = 1_000
    print("Grapher (default networks, full-length episodes):")
    if args.smoke:
        grapher = grapher_speed(default, members=3, episodes=2, rounds=1, spin=100_000)
    elif args.quick:
        grapher = grapher_speed(default, members=5, episodes=16, rounds=1)
    else:
        grapher = grapher_speed(default, members=6, episodes=32, rounds=3)
    print("Oracle:")
    paper_steps = steps // 2 if args.quick or args.smoke else steps
    oracle = {}
    for sampler in SAMPLERS:
        oracle.update(oracle_speed(default, "default", steps, sampler))
        if args.smoke:  # the same config twice: its figures stand for both
            oracle.update({k.replace("_default_", "_paper_"): v for k, v in oracle.items()})
            continue
        oracle.update(oracle_speed(paper, "paper", paper_steps, sampler))
    print("Generation (default config, shortened budgets):")
    short = dataclasses.replace(
        default,
        oracle=dataclasses.replace(default.oracle, env_steps=steps),
        # generation 0 pre-trained here (the default adopts a shipped population)
        pretrain=dataclasses.replace(
            default.pretrain, env_steps=steps, population="none", learner_start="random"
        ),
    )
    parts = generation_breakdown(short)
    if started:
        ray.shutdown()
    batched, previous = "batched", "pettingzoo"
    summary = {
        "oracle_sampled_env_steps_per_s": oracle[f"oracle_sampled_steps_per_s_default_{batched}"],
        "oracle_overall_env_steps_per_s": oracle[f"oracle_env_steps_per_s_default_{batched}"],
        "paper_oracle_overall_env_steps_per_s": oracle[f"oracle_env_steps_per_s_paper_{batched}"],
        "minutes_per_1e6_paper_oracle": oracle[f"oracle_1e6_minutes_paper_{batched}"],
        "pettingzoo_path_sampled_env_steps_per_s": oracle[
            f"oracle_sampled_steps_per_s_default_{previous}"
        ],
        "pettingzoo_path_overall_env_steps_per_s": oracle[
            f"oracle_env_steps_per_s_default_{previous}"
        ],
        "pettingzoo_path_minutes_per_1e6_paper_oracle": oracle[
            f"oracle_1e6_minutes_paper_{previous}"
        ],
        **grapher,
        **{f"generation_{k}": v for k, v in parts.items()},
    }
    summary["sampling_speedup"] = (
        summary["oracle_sampled_env_steps_per_s"]
        / summary["pettingzoo_path_sampled_env_steps_per_s"]
    )
    print(
        f"  → batched env runner / PettingZoo path, default PPO: sampled "
        f"{summary['sampling_speedup']:.1f}×; paper PPO 1e6 steps in "
        f"{summary['minutes_per_1e6_paper_oracle']:.1f} min "
        f"(PettingZoo path {summary['pettingzoo_path_minutes_per_1e6_paper_oracle']:.1f} min)"
    )
    print(json.dumps({k: round(v, 4) for k, v in summary.items()}))


if __name__ == "__main__":
    main()
