"""Fly a learned team as Crazyflies: `python -m hola_ray fly ONNX_OR_POLICY`.

The same arena, bars and DACOOP evaders as training, but each pursuer is a Crazyflie 2.x
(pybullet rigid body, the firmware's PID cascade) holding 1 m and tracking the velocity
set-point its policy's heading commands each control period; the policies read
observations built from the drones' true positions. The same seeds and teams are also
played in the kinematic arena, so the two columns are paired.

ONNX_OR_POLICY: an ONNX file written by `python -m hola_ray export` (played by
onnxruntime; its manifest beside it gives the scenario), or anything export takes (a run
directory, generation folder, .pt file or pool member id). It sits in seat 0; the other
seats are copies of it, or `--teammates` (registry names, pool member ids or files, one per
seat). Prints both columns; the last line is JSON: success, collision, length and
kinematic_success, kinematic_collision, kinematic_length (and their standard errors).
`--replay OUT.png` draws the run's first episode flown beside the arena's replay of it.
`--guard` plays the flight and the arena through the ground station's safety filter
(`hola_ray.flight.guard`).
`--identify` fits the arena's response model to the flown drone instead
(env.pursuer_response and env.pursuer_response_delay, for training closer to it).
`--pursuers N` flies a team of N (2 to 5) and `--arena NAME` another arena (contract §6):
a policy trained on observation slots reads any team up to them; one trained for another
team, seat 0 or a teammate, flies through `hola_ray.policies.adapter.ScenarioAdapter`.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections import Counter
from pathlib import Path
from typing import Any

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import PursuitConfig, TeamChangeConfig
from hola_ray.flight.guard import Guard

INSTALL = "pip install -e '.[deploy]'"


def learner(spec: str, evaders: int | None) -> tuple[Any, PursuitConfig]:
    """The policy of seat 0 and the scenario it flies."""
    if spec.endswith(".onnx"):
        from hola_ray.policies.deploy import OnnxPolicy
        from hola_ray.policies.registry import trained_scenario

        config = trained_scenario(spec)
        if evaders not in (None, config.n_evaders):
            raise ValueError(f"{spec} flies {config.n_evaders} evader(s), not {evaders}")
        return OnnxPolicy(spec), config
    from hola_ray.commands.export import resolve
    from hola_ray.evaluation.pools import MEMBERS

    policy, _ = resolve(spec)
    config = policy.config
    if evaders is not None and evaders != config.n_evaders:
        if spec not in MEMBERS:
            raise ValueError(f"{spec} was trained for {config.n_evaders} evader(s), not {evaders}")
        from hola_ray.commands.replay import resolve as by_name

        config = dataclasses.replace(config, n_evaders=evaders)
        policy = by_name(spec, config)  # a pool member plays other evader counts adapted
    return policy, config


def flown_scenario(config: PursuitConfig, pursuers: int | None, arena: str | None) -> PursuitConfig:
    """`config` flown by a fixed team of `pursuers` in `arena` (either unset: its own),
    observed in its own slots or in as many as the team where that is larger."""
    flown = dataclasses.replace(config, team=TeamChangeConfig(), arenas=())
    if arena is not None:
        flown = flown.in_arena(arena)
    if pursuers is not None:
        slots = max(config.pursuer_slots, pursuers)
        flown = dataclasses.replace(flown, n_pursuers=pursuers, obs_pursuers=slots)
    return flown


def seated(spec: str, policy: Any, config: PursuitConfig) -> Any:
    """`policy` (of `spec`) as it flies `config`: read as it is where `config`'s slots are
    its own, else through the adapter (`fitted`), an ONNX file as a torch policy."""
    from hola_ray.policies.adapter import fitted

    if spec.endswith(".onnx") and policy.config.layout == config.layout:
        from hola_ray.policies.deploy import OnnxPolicy

        return OnnxPolicy(spec, config)  # a team its slots hold, read as it is
    return fitted(config, policy)


def teammate(name: str, config: PursuitConfig) -> Any:
    """A teammate by registry name, pool member id (adapted by its pool) or file (built
    in the scenario it was trained in, then fitted to `config`)."""
    from hola_ray.commands.replay import resolve as by_name

    if Path(name).exists():
        policy, _ = learner(name, None)
        return seated(name, policy, config)
    return by_name(name, config)


def kinematic(config: PursuitConfig) -> PursuitConfig:
    """`config` with the paper's kinematics (a heading change acts at once)."""
    return dataclasses.replace(config, pursuer_response=1.0, pursuer_response_delay=0)


def columns(
    team: list[Any],
    config: PursuitConfig,
    episodes: int,
    seed: int,
    batch: int = 16,
    guard: Guard | None = None,
) -> dict[str, Any]:
    """The same episodes played three ways: {"" (flown as Crazyflies), "kinematic_" (the
    paper's arena), and "model_" (`config`'s own arena, only when it has a response
    model)} → its `RolloutResult`; and "flight_s", the flight's wall time. With a `guard`
    (the ground station's safety filter) the flight and the paper's arena play through it
    (`GuardedArena` moves at once, so there is no "model_" column)."""
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.flight import Crazyflies, GuardedArena

    arena = None if guard is None else functools.partial(GuardedArena, guard=guard)

    def play(config: PursuitConfig, dynamics: Any = arena) -> Any:
        return rollout(config, team, episodes, seed=seed, batch_size=batch, dynamics=dynamics)

    start = time.perf_counter()
    flown = play(config, functools.partial(Crazyflies, guard=guard))
    flight_s = time.perf_counter() - start
    paper = kinematic(config)
    out = {"": flown, "kinematic_": play(paper)}
    if paper != config and guard is None:  # trained with a response model: its own arena
        out["model_"] = play(config)
    return out | {"flight_s": flight_s}


def summary(played: dict[str, Any]) -> dict[str, Any]:
    """`columns`' results summarised: success, collision, length (± s.e.), seat 0's crash
    rate and its teammates' (the mean over their seats) of each, prefixed by its column."""
    played = dict(played)
    flight_s = played.pop("flight_s")
    out: dict[str, Any] = {"episodes": played[""].episodes}
    for prefix, result in played.items():
        rates = result.summary()
        for key in ("success", "collision", "length"):
            out[f"{prefix}{key}"] = round(rates[key], 4)
            out[f"{prefix}{key}_se"] = round(rates[f"{key}_se"], 4)
        out[f"{prefix}crash_seat0"] = round(float(result.crashed[:, 0].mean()), 4)
        out[f"{prefix}crash_mates"] = round(float(result.crashed[:, 1:].mean()), 4)
    out["flight_s"] = round(flight_s, 1)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m hola_ray fly", description=__doc__)
    parser.add_argument(
        "policy", nargs="?", help="an exported .onnx file, or a run directory, .pt or member id"
    )
    parser.add_argument(
        "--identify",
        action="store_true",
        help="fit the arena's response model (env.pursuer_response, _delay) to the flown drone",
    )
    parser.add_argument("--teammates", nargs="+", default=None, help="the other seats' policies")
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--evaders", type=int, default=None, help="a pool member's evader count")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pursuers", type=int, default=None, help="fly a team of N (2-5)")
    parser.add_argument("--arena", default=None, help="fly another arena: open, bar, blocks, paper")
    parser.add_argument("--horizon", type=int, default=None, help="shorter episodes (tests)")
    parser.add_argument(
        "--replay", type=Path, default=None, help="PNG: the first episode flown and in the arena"
    )
    parser.add_argument(
        "--guard",
        action="store_true",
        help="the ground station's safety filter on the set-points (hola_ray/flight/guard.py)",
    )
    parser.add_argument("--json", action="store_true", help="print only the JSON line")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        return fail(f"--episodes must be >= 1, got {args.episodes}")
    try:
        import pybullet  # noqa: F401
    except ImportError:
        return fail(f"flying needs pybullet: {INSTALL}")
    if args.identify:
        from hola_ray.flight.identify import identify

        print(json.dumps(identify()))
        return 0
    if args.policy is None:
        return fail("give the policy to fly (an .onnx file, run directory, .pt or member id)")
    try:
        seat0, config = learner(args.policy, args.evaders)
        if args.pursuers is not None or args.arena is not None or config.team.open:
            config = flown_scenario(config, args.pursuers, args.arena)
            seat0 = seated(args.policy, seat0, config)
        if args.horizon is not None:
            config = dataclasses.replace(config, horizon=args.horizon)  # checked on creation
        mates = args.teammates or [args.policy] * (config.n_pursuers - 1)
        if len(mates) != config.n_pursuers - 1:
            raise ValueError(f"give {config.n_pursuers - 1} teammates, got {len(mates)}")
        team = [seat0] + [
            seat0 if (name == args.policy and args.teammates is None) else teammate(name, config)
            for name in mates
        ]
    except (ValueError, ConfigError, OSError, ImportError) as err:
        return fail(str(err))
    guard = Guard() if args.guard else None
    figures = summary(columns(team, config, args.episodes, args.seed, guard=guard))
    figures |= {
        "guard": dataclasses.asdict(guard) if guard is not None else None,
        "policy": args.policy,
        "teammates": mates,
        "scenario": f"{config.n_pursuers} vs {config.n_evaders}",
    }
    if args.replay is not None:
        from hola_ray.evaluation.stats import episode_seeds
        from hola_ray.flight.replay import draw_flight

        first = int(episode_seeds(args.seed, 1)[0])  # the first episode the figures count
        draw_flight(config, team, first, args.replay, guard=guard)
        if not args.json:
            print(f"wrote {args.replay}")
    if not args.json:
        print(
            f"{args.policy} with {teammates_phrase(args.policy, mates)}, {figures['scenario']}, "
            f"{args.episodes} episodes (seed {args.seed}):"
        )
        for key in ("success", "collision", "length", "crash_seat0", "crash_mates"):
            print(
                f"  {key:12s} flown {figures[key]:8.3f}   arena {figures['kinematic_' + key]:8.3f}"
            )
    print(json.dumps(figures))
    return 0


def teammates_phrase(policy: str, mates: list[str]) -> str:
    """`mates` as the report's first line names them: a repeated name once, with its count,
    and the policy's own copies as such."""
    parts = []
    for mate, count in Counter(mates).items():
        name = "itself" if mate == policy else mate
        parts.append(name if count == 1 else f"{count} copies of {name}")
    return ", ".join(parts)


def script() -> None:
    """`hola-fly` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
