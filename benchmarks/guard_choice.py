"""How the guard's settings were chosen: learners flown through each candidate guard as three
copies and beside the validation teammates (what a choice may rest on; never Greedy, VICSEK
or a pool member), flown only.

    python benchmarks/guard_choice.py EPISODES RUN [RUN ...] [--horizon STEPS]

Each RUN's best.pt flies on the same episode seeds (seed 0) with no guard and with each
candidate (margin m, gain /s); per candidate and team, the mean over the runs of success,
collision, the learner's own crash rate and its teammates'. Judged by the paper's rules
whatever arena the runs trained in (`--horizon` shortens its episodes: a smoke run). The
last line is one JSON object.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import validation_mates
from hola_ray.evaluation.rollout import rollout
from hola_ray.flight import Crazyflies, Guard
from hola_ray.policies.learned import MLPPolicy

CANDIDATES = (None, Guard(0.05, 2.0), Guard(0.02, 2.0), Guard(0.05, 4.0), Guard(0.10, 2.0))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/guard_choice.py")
    parser.add_argument("episodes", type=int)
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--horizon", type=int, default=PursuitConfig().horizon)
    args = parser.parse_args(argv)
    episodes, runs = args.episodes, args.runs
    out = []
    for guard in CANDIDATES:
        drones = functools.partial(Crazyflies, guard=guard)
        rows: dict[str, list] = {"copies": [], "validation": []}
        for run in runs:
            policy = MLPPolicy.load(f"{run}/best.pt")
            trained = policy.config
            config = PursuitConfig(
                n_pursuers=trained.n_pursuers, n_evaders=trained.n_evaders, horizon=args.horizon
            )
            mates = validation_mates(config, config.n_pursuers - 1)
            teams = {"copies": [policy] * config.n_pursuers, "validation": [policy, *mates]}
            for label, team in teams.items():
                flown = rollout(config, team, episodes, seed=0, batch_size=16, dynamics=drones)
                rows[label].append(
                    [
                        flown.success.mean(),
                        flown.collision.mean(),
                        flown.crashed[:, 0].mean(),
                        flown.crashed[:, 1:].mean(),
                    ]
                )
        for label, values in rows.items():
            success, collision, own, mates_ = np.mean(values, axis=0).round(4).tolist()
            name = "none" if guard is None else f"margin {guard.margin}, gain {guard.gain}"
            print(
                f"{name} | {label}: success {success:.3f} collision {collision:.3f} "
                f"own crash {own:.3f} teammates' crash {mates_:.3f}",
                flush=True,
            )
            out.append(
                {"guard": name, "team": label, "success": success, "collision": collision}
                | {"own_crash": own, "mates_crash": mates_}
            )
    print(json.dumps({"episodes": episodes, "runs": runs, "rows": out}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
