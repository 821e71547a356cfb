"""Every method's Oracle, per learner transition: the lean PPO update against RLlib's own
(or any two values of one Oracle setting, `--against`).

    python benchmarks/oracle_speed.py [--config configs/default.yaml] [--set oracle.x=y]
                                      [--samples 60000] [--repeats 2]
    python benchmarks/oracle_speed.py --against oracle.overlap=false,true

The seven methods seat the Oracle in three ways (`Method.seating`): self-play (sp: the
learner in every seat), a learner beside frozen partners drawn by φ (hola, hola_r,
uniform, fcp, mep, pbt: `population.max_size` partner modules), and MEP pre-training
(every member trained, with the population-entropy bonus). For each, the same config is
trained with `oracle.update: rllib` (RLlib's learner pipeline, minibatch iterator and PPO
loss) and `oracle.update: lean` (`hola_ray.oracle.learner.OracleLearner`), interleaved,
`--repeats` times each, `--samples` learner transitions (MEP pre-training: env steps, its
budget's unit) after a warm-up iteration. `--against KEY=A,B` compares KEY's values A and
B instead (default `oracle.update=rllib,lean`). It prints one JSON line per measurement
and, last, one with the median learner transitions per second of each and their ratio
(B ÷ A).
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEATINGS = ("self-play", "partners", "mep-pretrain")


def oracle_for(config, seating: str):
    from hola_ray.config.oracle import Seating
    from hola_ray.oracle import LEARNER, Oracle
    from hola_ray.oracle.mapping import member_module

    c = config
    if seating == "self-play":
        return Oracle(c.env, c.oracle, Seating(), c.seed)
    if seating == "mep-pretrain":
        n = c.population.initial_size
        return Oracle(c.env, c.oracle, Seating(mep_members=n, mep_alpha=c.pretrain.alpha), c.seed)
    k = c.population.max_size
    oracle = Oracle(c.env, c.oracle, Seating(partners=k), c.seed)
    base = oracle.weights([LEARNER])[LEARNER]
    rng = np.random.default_rng(0)
    oracle.set_partners(
        {
            member_module(i): {
                name: (np.asarray(v) + rng.normal(0, 0.3, np.shape(v))).astype(np.float32)
                for name, v in base.items()
            }
            for i in range(k)
        }
    )
    oracle.set_phi({member_module(i): 1.0 / k for i in range(k)})
    return oracle


def measure(config, seating: str, key: str, value: str, samples: int) -> dict:
    from hola_ray.cli import apply_sets
    from hola_ray.methods.config import RunConfig

    data = apply_sets(config.to_dict(), [f"{key}={value}", "oracle.budget=learner_samples"])
    c = RunConfig.from_dict(data)
    oracle = oracle_for(c, seating)
    try:
        oracle.train(1, progress=False)  # warm-up: one iteration
        stats = oracle.train(samples, progress=False)
    finally:
        oracle.stop()
    # (in MEP pre-training every member is trained: every seat's transition counts)
    per_s = stats.learner_samples / max(stats.wall_s, 1e-9)
    return {
        "seating": seating,
        key: value,
        "learner_samples_per_s": round(per_s, 1),
        "learn_s": round(stats.learn_s, 2),
        "sample_s": round(stats.sample_s, 2),
        "wall_s": round(stats.wall_s, 2),
        "learner_samples": stats.learner_samples,
        "env_steps": stats.env_steps,
        "gradient_steps": stats.gradient_steps,
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "default.yaml")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    parser.add_argument("--samples", type=int, default=60_000)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--seatings", nargs="+", default=list(SEATINGS), choices=SEATINGS)
    parser.add_argument(
        "--against",
        default="oracle.update=rllib,lean",
        help="KEY=A,B: the setting compared and its two values (default: %(default)s)",
    )
    args = parser.parse_args(argv)
    key, _, values = args.against.partition("=")
    first, second = values.split(",")

    import ray

    from hola_ray.commands.run import read_config
    from hola_ray.process import join_or_init_ray

    config = read_config(args.config, args.sets)
    started = join_or_init_ray("oracle_speed", num_cpus=2)
    rows = []
    for _ in range(args.repeats):
        for seating in args.seatings:
            for value in (first, second):
                rows.append(measure(config, seating, key, value, args.samples))
                print(json.dumps(rows[-1]), flush=True)
    if started:
        ray.shutdown()
    summary: dict = {
        "config": str(args.config),
        "sets": args.sets,
        "samples": args.samples,
        "against": args.against,
    }
    for seating in args.seatings:
        median = {
            v: statistics.median(
                r["learner_samples_per_s"] for r in rows if r["seating"] == seating and r[key] == v
            )
            for v in (first, second)
        }
        summary[seating] = {
            f"{first}_per_s": median[first],
            f"{second}_per_s": median[second],
            "ratio": round(median[second] / median[first], 2),
        }
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
