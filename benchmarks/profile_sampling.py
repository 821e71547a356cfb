"""Where an Oracle env runner's sampling time goes: cProfile inside the env runner actor.

    python benchmarks/profile_sampling.py [--steps 40000] [--top 14] [--sampler batched]
                                          [--config FILE] [--set section.field=value ...]

For each `oracle.sampler` (batched, pettingzoo) the default run's Oracle is built, warmed
up with one training iteration, and then the remote env runner profiles its own
`sample()` calls over `--steps` env steps (no learner update in between). Printed per
sampler: env steps/s inside the profiler, and the functions with the most time of their own
(tottime), grouped under short names. cProfile's overhead slows Python-heavy code most, so
the rates here are below `benchmarks/service_speed.py`'s; the shares are what it is for.
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import json
import pstats
import time
from pathlib import Path

import ray

from hola_ray.config.oracle import SAMPLERS
from hola_ray.homes import ROOT
from hola_ray.process import join_or_init_ray


def profile_runner(runner, steps: int, top: int) -> dict:
    per_call = runner.config.train_batch_size_per_learner
    profiler = cProfile.Profile()
    done = 0
    start = time.perf_counter()
    profiler.enable()
    while done < steps:
        episodes = runner.sample(num_timesteps=per_call)
        done += sum(len(ep) for ep in episodes)
    profiler.disable()
    wall = time.perf_counter() - start
    stats = pstats.Stats(profiler)
    rows = []
    total = sum(v[2] for v in stats.stats.values())
    for (path, line, name), (_, ncalls, tottime, _cum, _) in sorted(
        stats.stats.items(), key=lambda kv: -kv[1][2]
    )[:top]:
        short = path.split("site-packages/")[-1].split(f"{ROOT}/")[-1]
        rows.append(
            {
                "function": f"{short}:{line}({name})",
                "calls": ncalls,
                "tottime_s": round(tottime, 3),
                "share": round(tottime / total, 3),
            }
        )
    return {"env_steps": done, "wall_s": wall, "rows": rows}


def main(argv: list[str] | None = None) -> None:
    from hola_ray.commands.run import read_config

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=40_000)
    parser.add_argument("--top", type=int, default=14)
    parser.add_argument("--sampler", choices=SAMPLERS, help="profile only this sampler")
    parser.add_argument("--config", type=Path, help="a run config (default: the embedded one)")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    args = parser.parse_args(argv)
    started = join_or_init_ray("profile_sampling", num_cpus=2)
    default = read_config(args.config, args.sets)
    summary = {}
    for sampler in [args.sampler] if args.sampler else SAMPLERS:
        config = dataclasses.replace(
            default, oracle=dataclasses.replace(default.oracle, sampler=sampler)
        )
        oracle = config.strategy.make_oracle(config)
        try:
            oracle.train(config.oracle.train_batch, progress=False)  # compile, warm up
            (result,) = oracle.algo.env_runner_group.foreach_env_runner(
                lambda r: profile_runner(r, args.steps, args.top), local_env_runner=False
            )
        finally:
            oracle.stop()
        rate = result["env_steps"] / result["wall_s"]
        summary[f"{sampler}_profiled_env_steps_per_s"] = round(rate)
        print(
            f"sampler {sampler}: {result['env_steps']:,} env steps in {result['wall_s']:.1f} s "
            f"under cProfile ({rate:,.0f} steps/s, {1e6 / rate:.0f} µs per env step)"
        )
        for row in result["rows"]:
            print(
                f"  {row['share']:6.1%}  {row['tottime_s']:7.2f} s  {row['calls']:>9}  "
                f"{row['function']}"
            )
    if started:
        ray.shutdown()
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
