"""What the pursuers hit, and when: every crash of a team classified by what was within
reach at the step it happened.

    python benchmarks/crashes.py POLICY [POLICY ...] [--teammates copies|validation|NAME NAME]
        [--episodes 200] [--seed 5] [--flown] [--judged]

POLICY: a run directory (its learner.pt), a generation folder or an export file, played in
its own trained scenario. The learner sits in seat 0; its teammates are its own copies
(`copies`, the default: how its own population would fly), the first n_p − 1 validation
teammates (`validation`, what training may see) or the hand-written policies named. A
crash is a `wall` (within the safe radius of the arena's edge), a `bar` (of an obstacle
bar), a `mate` (another active pursuer within the pursuer–pursuer distance) or a `wreck`
(anything else: a disabled pursuer's last position). Prints one line per policy and as its
last line one JSON object. It measures; it never chooses a setting. `--flown` flies the
same episodes as Crazyflies (`hola_ray.flight`, judged on the drones' true positions) and
prints both: what the drones hit that the arena's pursuers did not. `--judged` plays each
policy in the scenario it is held to its bar in (`PursuitConfig.judged`: a member of an open
teams' population as three copies in the paper's arena, read in its own slots), and a `bar`
is then any obstacle, a disc included.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.env.geometry import wrap
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.base import seated
from hola_ray.policies.registry import load_policy, make_policy, trained_scenario

CAUSES = ("wall", "bar", "mate", "wreck")


def bar_distance(config: PursuitConfig, p: np.ndarray) -> float:
    """Distance from point p to the nearest obstacle bar (0 inside one)."""
    best = np.inf
    for cx, cy, w, h in config.obstacles:
        dx = max(abs(p[0] - cx) - w / 2, 0.0)
        dy = max(abs(p[1] - cy) - h / 2, 0.0)
        best = min(best, float(np.hypot(dx, dy)))
    for cx, cy, r in config.discs:
        best = min(best, max(float(np.hypot(p[0] - cx, p[1] - cy)) - r, 0.0))
    return best


def crashes(config: PursuitConfig, team: list, episodes: int, seed: int, dynamics=None) -> dict:
    """Play `episodes` episodes with `team` (one policy per seat) and classify every crash;
    `dynamics` as `rollout` takes it (`hola_ray.flight.Crazyflies` flies them)."""
    n_p = config.n_pursuers
    team = seated(team)
    env = BatchedPursuit(config, episodes)
    obs = env.reset(seeds=episode_seeds(seed, episodes))
    fly = dynamics(env) if dynamics is not None else None
    for policy in team:
        policy.reset(np.ones(episodes, dtype=bool))
    causes = np.zeros((n_p, len(CAUSES)), dtype=int)
    steps: list[int] = []
    evaders_left: list[int] = []
    mates_left: list[int] = []  # at each of the learner's crashes: teammates still flying
    # at each crash into a teammate, from the step before: the nearest live evader's
    # distance and the angle between the two pursuers' headings
    mate_evader: list[float] = []
    mate_angle: list[float] = []
    while not env.done.all():
        actions = np.stack([team[i].act(obs[:, i]) for i in range(n_p)], axis=1)
        before = env.pursuer_active & ~env.done[:, None]
        was_at, was_heading = env.pursuer_pos.copy(), env.pursuer_heading.copy()
        evaders_at, evaders_alive = env.evader_pos.copy(), env.evader_alive.copy()
        actions = actions.reshape(episodes, n_p)
        obs = env.step(actions, fly(actions) if fly is not None else None).obs
        for b, i in zip(*np.nonzero(before & ~env.pursuer_active), strict=True):
            p = env.pursuer_pos[b, i]
            wall = min(p[0], config.arena_width - p[0], p[1], config.arena_height - p[1])
            mates = [
                j
                for j in range(n_p)
                if j != i
                and before[b, j]
                and np.hypot(*(env.pursuer_pos[b, j] - p)) < config.pursuer_collision_distance
            ]
            mate = bool(mates)
            if mate:
                gaps = np.linalg.norm(evaders_at[b] - was_at[b, i], axis=-1)
                mate_evader.append(float(np.where(evaders_alive[b], gaps, np.inf).min()))
                turn = was_heading[b, mates[0]] - was_heading[b, i]
                mate_angle.append(abs(wrap(float(turn))))
            if wall < config.safe_radius:
                kind = "wall"
            elif bar_distance(config, p) < config.safe_radius:
                kind = "bar"
            else:
                kind = "mate" if mate else "wreck"
            causes[i, CAUSES.index(kind)] += 1
            steps.append(int(env.t[b]))
            evaders_left.append(int(env.evader_alive[b].sum()))
            if i == 0:
                mates_left.append(int(before[b].sum()) - 1)
    return {
        "episodes": episodes,
        "success": float(env.success.mean()),
        "collision": float(env.collided.mean()),
        "length": float(env.t.mean()),
        "crashes": dict(zip(CAUSES, causes.sum(axis=0).tolist(), strict=True)),
        "learner_crashes": dict(zip(CAUSES, causes[0].tolist(), strict=True)),
        "seat_crash_rate": (causes.sum(axis=1) / episodes).round(4).tolist(),
        "crash_step_quartiles": np.percentile(steps, [25, 50, 75]).tolist() if steps else [],
        "evaders_left_at_crash": np.bincount(evaders_left, minlength=config.n_evaders + 1)
        .astype(int)
        .tolist(),
        "learner_mates_left_at_crash": np.bincount(mates_left, minlength=n_p).astype(int).tolist(),
        "mate_crash_evader_m_quartiles": quartiles(mate_evader),
        "mate_crash_heading_angle_deg_quartiles": quartiles(np.degrees(mate_angle)),
    }


def quartiles(values) -> list[float]:
    """The 25th, 50th and 75th percentiles, rounded; [] for none."""
    return np.percentile(values, [25, 50, 75]).round(2).tolist() if len(values) else []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/crashes.py", description=__doc__)
    parser.add_argument("policies", nargs="+", type=Path)
    parser.add_argument("--teammates", nargs="+", default=["copies"])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--flown", action="store_true", help="also flown as Crazyflies")
    parser.add_argument(
        "--judged", action="store_true", help="in the scenario a member is held to its bar in"
    )
    args = parser.parse_args(argv)
    out = {}
    for path in args.policies:
        config = trained_scenario(path) or PursuitConfig()
        if args.judged:
            config = config.judged()
        learner = load_policy(path, config)
        if args.teammates == ["copies"]:
            mates = [learner] * (config.n_pursuers - 1)
        elif args.teammates == ["validation"]:
            from hola_ray.evaluation.pools import validation_mates

            mates = validation_mates(config, config.n_pursuers - 1)
        elif len(args.teammates) == config.n_pursuers - 1:
            mates = [make_policy(n, config) for n in args.teammates]
        else:
            print(
                f"error: --teammates copies, validation or {config.n_pursuers - 1} names",
                file=sys.stderr,
            )
            return 2
        team = [learner, *mates]
        if args.flown:
            from hola_ray.commands.fly import kinematic
            from hola_ray.flight import Crazyflies

            config = kinematic(config)  # the arena column plays the paper's kinematics
            played = {
                "arena ": crashes(config, team, args.episodes, args.seed),
                "flown ": crashes(config, team, args.episodes, args.seed, Crazyflies),
            }
        else:
            played = {"": crashes(config, team, args.episodes, args.seed)}
        for column, r in played.items():
            out[f"{column}{path}"] = r
            print(
                f"{column}{path}: success {r['success']:.1%}, collision {r['collision']:.1%}, "
                f"crashes {r['crashes']} (the learner's {r['learner_crashes']}), per seat "
                f"{r['seat_crash_rate']}, at step {r['crash_step_quartiles']} (quartiles); "
                f"teammates flying when the learner crashed {r['learner_mates_left_at_crash']}; "
                f"crashes into a teammate: the nearest evader "
                f"{r['mate_crash_evader_m_quartiles']} m away, the two headings "
                f"{r['mate_crash_heading_angle_deg_quartiles']}° apart (quartiles)"
            )
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
