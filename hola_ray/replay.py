"""Watch an episode: `python -m hola_ray.replay --team vicsek vicsek greedy --seed 3`.

Writes an animated GIF and a PNG of the trajectories (arena, obstacles, capture and
collision marks) and prints the episode's metrics.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hola_ray.env.config import PursuitConfig
from hola_ray.env.render import animate_trajectory, plot_trajectory
from hola_ray.evaluation.trajectory import record
from hola_ray.policies.registry import make_policy, policy_names


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m hola_ray.replay", description=__doc__)
    parser.add_argument(
        "--team",
        nargs="+",
        default=["vicsek"],
        help="policy per pursuer slot (one name fills every slot); known: "
        f"{', '.join(policy_names()[:2])}, apf-a-0..apf-a-23",
    )
    parser.add_argument(
        "--config", type=Path, help="YAML with the pursuit config (or an env: section)"
    )
    parser.add_argument("--evaders", type=int, help="override the number of evaders")
    parser.add_argument("--seed", type=int, default=0, help="episode seed")
    parser.add_argument("--out", type=Path, default=Path("replays"), help="output folder")
    parser.add_argument("--stride", type=int, default=2, help="steps per GIF frame")
    args = parser.parse_args(argv)

    config = PursuitConfig.from_yaml(args.config) if args.config else PursuitConfig()
    if args.evaders is not None:
        config = PursuitConfig.from_dict({**config.to_dict(), "n_evaders": args.evaders})
    names = args.team * config.n_pursuers if len(args.team) == 1 else args.team
    if len(names) != config.n_pursuers:
        parser.error(f"--team needs 1 or {config.n_pursuers} names, got {len(names)}")
    team = [make_policy(name, config) for name in names]
    traj = record(config, team, seed=args.seed)

    args.out.mkdir(parents=True, exist_ok=True)
    stem = f"{'-'.join(names)}_seed{args.seed}"
    png = args.out / f"{stem}.png"
    gif = args.out / f"{stem}.gif"
    plot_trajectory(config, traj, str(png))
    frames = animate_trajectory(config, traj, str(gif), stride=args.stride)
    print(f"metrics: {traj.metrics}")
    print(f"wrote {png} and {gif} ({frames} frames)")


if __name__ == "__main__":
    main()
