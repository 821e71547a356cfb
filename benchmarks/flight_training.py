"""Flown as Crazyflies: learners trained in the paper's arena ("kinematic") against learners
trained in a changed one ("response": the fitted response model env.pursuer_response, or
any other env setting), seed by seed, every one judged by the paper's rules.

    python benchmarks/flight_training.py EPISODES BASE_RUN,BASE_RUN,... NEW_RUN,NEW_RUN,...
        [--guard] [--teams copies validation hand] [--horizon STEPS]

Each run's best.pt flies (and plays the paper's kinematic arena) on the same episode seeds
in three copies, beside the validation teammates (sp-v1, sp-v2: what a choice may rest on)
and beside Greedy + VICSEK (evaluation teammates: measured, never chosen on). The runs pair
up in the order given (training seed i of each arm); the difference response − kinematic
is averaged over the pairs, with a 95 % bootstrap interval that resamples the episodes
within each pair (with few pairs it leaves out most of the seed-to-seed noise: read the
per-pair values beside it). `--guard` flies (and plays the arena) through the ground
station's safety filter; `--teams` plays only the teams named; `--horizon` shortens the
episodes (a smoke run). The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from hola_ray.commands.fly import columns
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import validation_mates
from hola_ray.flight import Guard
from hola_ray.policies.learned import MLPPolicy
from hola_ray.policies.registry import make_policy

TEAMS = ("copies", "validation", "hand")


def teams(policy, config):
    hand = [make_policy("greedy", config), make_policy("vicsek", config)]
    return {
        "copies": [policy] * config.n_pursuers,
        "validation": [policy, *validation_mates(config, config.n_pursuers - 1)],
        "hand": [policy, *hand],
    }


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("episodes", type=int)
    parser.add_argument("base")
    parser.add_argument("new")
    parser.add_argument("--guard", action="store_true")
    parser.add_argument("--teams", nargs="+", choices=TEAMS, default=list(TEAMS))
    parser.add_argument("--horizon", type=int, default=PursuitConfig().horizon)
    args = parser.parse_args(argv)
    episodes, guard = args.episodes, Guard() if args.guard else None
    arms = {"kinematic": args.base.split(","), "response": args.new.split(",")}
    out = {}
    for arm, runs in arms.items():
        for run in runs:
            policy = MLPPolicy.load(f"{run}/best.pt")
            # judged by the paper's rules whatever arena it trained in
            trained = policy.config
            config = PursuitConfig(
                n_pursuers=trained.n_pursuers, n_evaders=trained.n_evaders, horizon=args.horizon
            )
            for label, team in teams(policy, config).items():
                if label not in args.teams:
                    continue
                played = columns(team, config, episodes, seed=0, guard=guard)
                flown, arena = played[""], played["kinematic_"]
                out[(arm, run, label)] = {
                    "succ": flown.success,
                    "coll": flown.collision,
                    "own": flown.crashed[:, 0],
                }
                print(
                    f"{arm} {run} {label}: flown success {flown.success.mean():.3f} collision "
                    f"{flown.collision.mean():.3f} own crash {flown.crashed[:, 0].mean():.3f} | "
                    f"arena success {arena.success.mean():.3f} collision "
                    f"{arena.collision.mean():.3f}",
                    flush=True,
                )
    rng = np.random.default_rng(0)
    pairs = list(zip(arms["kinematic"], arms["response"], strict=True))
    summary = {}
    for label in args.teams:
        for key in ("succ", "coll", "own"):
            diffs = [
                out[("response", b, label)][key].astype(float)
                - out[("kinematic", a, label)][key].astype(float)
                for a, b in pairs
            ]
            mean = float(np.mean([d.mean() for d in diffs]))
            boots = [
                np.mean([d[rng.integers(0, len(d), len(d))].mean() for d in diffs])
                for _ in range(4000)
            ]
            lo, hi = np.percentile(boots, [2.5, 97.5])
            per = ", ".join(f"{d.mean() * 100:+.1f}" for d in diffs)
            summary[f"{label}_{key}"] = {"mean": mean, "ci95": [float(lo), float(hi)]}
            print(
                f"{label} {key}: response - kinematic = {mean * 100:+.1f} "
                f"[{lo * 100:+.1f}, {hi * 100:+.1f}] (per seed pair: {per})"
            )
    print(json.dumps({"episodes": episodes, "response_minus_kinematic": summary}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
