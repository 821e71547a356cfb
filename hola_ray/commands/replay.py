"""Watch an episode: `python -m hola_ray replay --team vicsek vicsek greedy --seed 3`.

A team mixes anything that plays: hand-written policies by name (greedy, vicsek,
apf-a-0 … apf-a-23), pool members by id (ppo-1, ppo-2, d3qn-g-1, d3qn-g-2; loaded from
the committed pools, hashes checked), and learned policies by path (a run directory's
learner.pt, or an exported .pt file), e.g.

    python -m hola_ray replay --team runs/x/learner.pt d3qn-g-1 vicsek

Writes an animated GIF and a PNG of the trajectories (arena, obstacles, capture and
collision marks, a legend naming each seat's policy) and prints the episode's metrics.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.render import animate_trajectory, plot_trajectory
from hola_ray.evaluation.trajectory import record
from hola_ray.policies.base import Policy
from hola_ray.policies.registry import load_policy, make_policy, policy_names, trained_scenario


def resolve(name: str, config: PursuitConfig) -> Policy:
    """A policy by registry name, pool member id, run directory or exported file."""
    from hola_ray.evaluation.pools import MEMBERS, POOLS, load_pool

    if name.lower() in policy_names():
        return make_policy(name, config)
    if name in MEMBERS:
        pool = next(p for p, ids in POOLS.items() if name in ids)
        return load_pool(pool, config)[name]
    if Path(name).exists():
        return load_policy(name, config)
    if "/" in name or name.endswith(".pt"):
        raise ValueError(f"{name}: no such file or directory")
    raise ValueError(
        f"unknown policy {name!r}: give a registry name ({', '.join(policy_names()[:2])}, "
        f"apf-a-0…23), a pool member ({', '.join(MEMBERS)}), a run directory or a .pt file"
    )


def main(argv: list[str] | None = None) -> int:
    """The command; 0, or 2 after one line on stderr for a bad input."""
    parser = OneLineParser(prog="python -m hola_ray replay", description=__doc__)
    parser.add_argument(
        "--team",
        nargs="+",
        default=["vicsek"],
        help="policy per pursuer slot (one fills every slot): a registry name "
        f"({', '.join(policy_names()[:2])}, apf-a-0..apf-a-23), a pool member id "
        "(ppo-1, d3qn-g-1 …), a run directory or an exported .pt file",
    )
    parser.add_argument(
        "--config", type=Path, help="YAML with the pursuit config (or an env: section)"
    )
    parser.add_argument(
        "--evaders",
        type=int,
        help="override the number of evaders (default: the first learned seat's, else 2)",
    )
    parser.add_argument("--seed", type=int, default=0, help="episode seed")
    parser.add_argument("--out", type=Path, default=Path("replays"), help="output folder")
    parser.add_argument("--stride", type=int, default=2, help="steps per GIF frame")
    args = parser.parse_args(argv)

    try:
        config, team = _team(args)
    except (ValueError, RuntimeError, ConfigError) as err:  # PoolError is a RuntimeError
        return fail(str(err))
    traj = record(config, team, seed=args.seed)

    args.out.mkdir(parents=True, exist_ok=True)
    names = [p.name for p in team]
    stem = f"{'-'.join(Path(n).stem for n in _names(args, config))}_seed{args.seed}"
    png = args.out / f"{stem}.png"
    gif = args.out / f"{stem}.gif"
    plot_trajectory(config, traj, str(png))
    frames = animate_trajectory(config, traj, str(gif), stride=args.stride)
    print(f"team: {', '.join(names)}")
    print(f"metrics: {traj.metrics}")
    print(f"wrote {png} and {gif} ({frames} frames)")
    return 0


def _names(args, config: PursuitConfig) -> list[str]:
    names = args.team * config.n_pursuers if len(args.team) == 1 else args.team
    if len(names) != config.n_pursuers:
        raise ValueError(f"--team needs 1 or {config.n_pursuers} names, got {len(names)}")
    return names


def _trained(name: str) -> PursuitConfig | None:
    """The scenario a seat's learner trained in; None for a hand-written policy's name."""
    try:
        return trained_scenario(name)
    except ValueError:
        return None


def _team(args) -> tuple[PursuitConfig, list[Policy]]:
    """The scenario and one policy per seat (a name given once fills every seat)."""
    config = PursuitConfig.from_yaml(args.config) if args.config else PursuitConfig()
    if args.evaders is None and args.config is None:
        # a learned seat's export says which scenario it was trained in: play that one
        trained = next(filter(None, (_trained(n) for n in args.team)), None)
        if trained is not None:
            config = trained
    if args.evaders is not None:
        config = dataclasses.replace(config, n_evaders=args.evaders)
    return config, [resolve(name, config) for name in _names(args, config)]


def script() -> None:
    """`hola-replay` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
