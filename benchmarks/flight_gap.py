"""The sim-to-sim gap: each policy flown as Crazyflies against the kinematic arena, on the
same seeds and teams (docs/flight.md's table).

    python benchmarks/flight_gap.py POLICY [POLICY ...] [--episodes 64] [--seed 0]
        [--evaders 1 2] [--json OUT.json] [--guard] [--horizon STEPS]

POLICY: a run directory (`RUN:best` for its best.pt), a generation folder, an export file
or a pool member id. Each policy flies in three copies and beside Greedy + VICSEK (the
policy in seat 0), in its own scenario; a pool member also in every scenario of
`--evaders` (adapted as the evaluation adapts it). Greedy and VICSEK are evaluation
teammates: this measures, it never chooses a setting. Per cell: success, collision and
length flown and in the paper's kinematic arena, the paired difference (flown − arena)
with a 95 % interval over the episodes, and who crashed (seat 0; a teammate, the mean over
the other seats); for a learner trained with a response model
(env.pursuer_response) also its own arena's figures (model_…, in the JSON). Prints a
Markdown table; the last line is one JSON object. `--guard` flies every drone through the
ground station's safety filter (`hola_ray.flight.guard`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from hola_ray.commands.export import resolve
from hola_ray.commands.fly import columns
from hola_ray.commands.replay import resolve as by_name
from hola_ray.evaluation.pools import MEMBERS
from hola_ray.flight.guard import Guard

HAND = ("greedy", "vicsek")


def paired(flown: np.ndarray, arena: np.ndarray) -> tuple[float, float]:
    """Mean of flown − arena and the half-width of its 95 % interval."""
    d = np.asarray(flown, float) - np.asarray(arena, float)
    return float(d.mean()), float(1.96 * d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0


def cell(team, config, episodes: int, seed: int, guard=None) -> dict:
    played = columns(team, config, episodes, seed, guard=guard)
    flown, arena = played[""], played["kinematic_"]
    out = {"episodes": episodes, "flight_s": round(played["flight_s"], 1)}
    if "model_" in played:  # trained with a response model: its own arena too
        out |= {
            f"model_{k}": round(float(np.mean(getattr(played["model_"], k))), 4)
            for k in ("success", "collision", "length")
        }
    for key in ("success", "collision", "length"):
        f, a = getattr(flown, key), getattr(arena, key)
        gap, half = paired(f, a)
        out |= {
            key: round(float(np.mean(f)), 4),
            f"kinematic_{key}": round(float(np.mean(a)), 4),
            f"{key}_gap": round(gap, 4),
            f"{key}_gap_95": round(half, 4),
        }
    for prefix, result in (("", flown), ("kinematic_", arena)):
        out[f"{prefix}crash_seat0"] = round(float(result.crashed[:, 0].mean()), 4)
        # each teammate's crash rate, averaged over their seats
        out[f"{prefix}crash_mates"] = round(float(result.crashed[:, 1:].mean()), 4)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policies", nargs="+")
    parser.add_argument("--episodes", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--evaders", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--guard", action="store_true", help="fly with the safety filter")
    parser.add_argument("--horizon", type=int, help="shorter episodes (a smoke run)")
    args = parser.parse_args(argv)
    guard = Guard() if args.guard else None
    rows = []
    print(
        "| policy | scenario | team | success flown / arena (gap) | collision flown / arena "
        "(gap) | length flown / arena | seat 0 crashed flown / arena | a teammate crashed "
        "flown / arena |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for spec in args.policies:
        best = spec.endswith(":best")
        name = spec.removesuffix(":best")
        policy, source = resolve(name, best)
        configs = [policy.config]
        if name in MEMBERS:
            configs = [dataclasses.replace(policy.config, n_evaders=k) for k in args.evaders]
        for config in configs:
            seat0 = policy if config == policy.config else by_name(name, config)
            for label, mates in (("3 copies", None), ("+ Greedy, VICSEK", HAND)):
                team = [seat0] * config.n_pursuers
                if mates is not None:
                    team = [seat0, *(by_name(m, config) for m in mates)]
                flown = config
                if args.horizon is not None:
                    flown = dataclasses.replace(config, horizon=args.horizon)
                r = cell(team, flown, args.episodes, args.seed, guard)
                scenario = f"{config.n_pursuers} vs {config.n_evaders}"
                rows.append({"policy": spec, "scenario": scenario, "team": label} | r)
                print(
                    f"| {spec} | {scenario} | {label} | "
                    f"{r['success']:.0%} / {r['kinematic_success']:.0%} "
                    f"({r['success_gap'] * 100:+.0f} ± {r['success_gap_95'] * 100:.0f}) | "
                    f"{r['collision']:.0%} / {r['kinematic_collision']:.0%} "
                    f"({r['collision_gap'] * 100:+.0f} ± {r['collision_gap_95'] * 100:.0f}) | "
                    f"{r['length']:.0f} / {r['kinematic_length']:.0f} | "
                    f"{r['crash_seat0']:.0%} / {r['kinematic_crash_seat0']:.0%} | "
                    f"{r['crash_mates']:.0%} / {r['kinematic_crash_mates']:.0%} |",
                    flush=True,
                )
    result = {"episodes": args.episodes, "seed": args.seed, "guard": args.guard, "cells": rows}
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
