"""A learner seated with two hand-written teammates, every seat in turn: the outside check
of the default run (issue: "its learner seated with Greedy + VICSEK, every seat in turn").

    python benchmarks/seated.py POLICY [POLICY ...] [--teammates greedy vicsek]
        [--episodes 200] [--seed 31]

POLICY: a run directory (its learner.pt), a generation folder or an export file. Per seat
s of the learner, `--episodes` episodes on the same seeds for every seat and every policy,
the teammates in the other seats in the order given; beside each learner, on the same
episodes, the first teammate's own policy in the learner's seat (what the seat would do
without the learner). Greedy and VICSEK are evaluation (HeT) teammates: this measures, it
never chooses a setting. The scenario is the learner's own (its export says). Prints one
line per policy and as its last line one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import episode_seeds, mean_and_se
from hola_ray.policies.registry import load_policy, make_policy, trained_scenario


def seated(learner, mates: list, config: PursuitConfig, episodes: int, seed: int) -> dict:
    """The learner in each seat in turn beside `mates`: success, collision, the learner's
    own crash rate and length, over all seats' episodes (each seat the same seeds)."""
    seeds = episode_seeds(seed, episodes)
    n_p = config.n_pursuers
    rows: dict[str, list[np.ndarray]] = {k: [] for k in ("success", "collision", "own", "length")}
    for s in range(n_p):
        team = list(mates)
        team.insert(s, learner)
        result = rollout(config, team, episodes, episode_seeds=seeds)
        rows["success"].append(result.success)
        rows["collision"].append(result.collision)
        rows["own"].append(result.crashed[:, s])
        rows["length"].append(result.length)
    out = {}
    for k, v in rows.items():
        mean, se = mean_and_se(np.concatenate(v).astype(np.float64))
        out[k], out[f"{k}_se"] = round(mean, 4), round(se, 4)
    out["episodes"] = episodes * n_p
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/seated.py", description=__doc__)
    parser.add_argument("policies", nargs="+", type=Path)
    parser.add_argument("--teammates", nargs="+", default=["greedy", "vicsek"])
    parser.add_argument("--episodes", type=int, default=200, help="episodes per seat")
    parser.add_argument("--seed", type=int, default=31)
    args = parser.parse_args(argv)
    out = {}
    for path in args.policies:
        config = trained_scenario(path) or PursuitConfig()
        if len(args.teammates) != config.n_pursuers - 1:
            print(f"error: give {config.n_pursuers - 1} teammates", file=sys.stderr)
            return 2
        mates = [make_policy(n, config) for n in args.teammates]
        learner = load_policy(path, config)
        mine = seated(learner, mates, config, args.episodes, args.seed)
        peer = seated(mates[0], mates, config, args.episodes, args.seed)
        out[str(path)] = {"learner": mine, f"{args.teammates[0]} in its seat": peer}
        print(
            f"{path}: success {mine['success']:.1%} ± {mine['success_se']:.1%}, collision "
            f"{mine['collision']:.1%}, its own seat crashed {mine['own']:.1%}, length "
            f"{mine['length']:.0f} | a {args.teammates[0]} there: {peer['success']:.1%}, "
            f"{peer['collision']:.1%}, own {peer['own']:.1%}"
        )
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
