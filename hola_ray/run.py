"""The main job: `python -m hola_ray.run [--config configs/default.yaml] [--out DIR]`.

Until the training service lands this is a demo of the arena: it plays a batch of
3-pursuer/2-evader episodes for each hand-written team of the config, prints success,
collision and length with standard errors, and writes a replay GIF and trajectory PNG.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from hola_ray.env.config import ConfigError, PursuitConfig
from hola_ray.env.render import animate_trajectory, plot_trajectory
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.trajectory import record
from hola_ray.policies.registry import make_policy, policy_names


@dataclass(frozen=True)
class DemoConfig:
    """What the demo plays."""

    teams: tuple[tuple[str, ...], ...] = (
        ("vicsek", "vicsek", "vicsek"),
        ("greedy", "greedy", "greedy"),
        ("vicsek", "greedy", "apf-a-9"),
    )
    """hand-written teams, one policy name per pursuer slot"""
    episodes: int = 200
    """episodes per team"""
    seed: int = 0
    """run seed; episode seeds derive from it"""
    replay_seed: int = 0
    """seed of the replayed episode of the first team"""

    def validate(self, env: PursuitConfig) -> None:
        if self.episodes < 1:
            raise ConfigError(f"demo.episodes must be >= 1, got {self.episodes}")
        if not self.teams:
            raise ConfigError("demo.teams must hold at least one team")
        known = set(policy_names())
        for k, team in enumerate(self.teams):
            if len(team) != env.n_pursuers:
                raise ConfigError(
                    f"demo.teams[{k}] must name {env.n_pursuers} policies (env.n_pursuers), "
                    f"got {len(team)}"
                )
            unknown = [name for name in team if name.lower() not in known]
            if unknown:
                raise ConfigError(f"demo.teams[{k}] names unknown policies {unknown}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DemoConfig:
        allowed = {"teams", "episodes", "seed", "replay_seed"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ConfigError(
                f"unknown key(s) demo.{', demo.'.join(unknown)}; allowed: {sorted(allowed)}"
            )
        data = dict(data)
        if "teams" in data:
            data["teams"] = tuple(tuple(str(n) for n in team) for team in data["teams"])
        return cls(**data)


def load(path: Path) -> tuple[PursuitConfig, DemoConfig]:
    """Read and validate a run config: an `env:` section and a `demo:` section."""
    data = yaml.safe_load(path.read_text()) or {}
    unknown = sorted(set(data) - {"env", "demo"})
    if unknown:
        raise ConfigError(f"unknown top-level key(s) {unknown} in {path}; allowed: env, demo")
    env = PursuitConfig.from_dict(data.get("env") or {})
    demo = DemoConfig.from_dict(data.get("demo") or {})
    demo.validate(env)
    return env, demo


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m hola_ray.run", description=__doc__)
    parser.add_argument(
        "--config",
        type=Path,
        help="run config YAML (default: the embedded small default, "
        "the same as configs/default.yaml)",
    )
    parser.add_argument("--out", type=Path, help="output folder (default runs/demo-<time>)")
    args = parser.parse_args(argv)
    if args.config is None:
        env_config, demo = PursuitConfig(), DemoConfig()
        demo.validate(env_config)
    else:
        env_config, demo = load(args.config)
    out = args.out or Path("runs") / time.strftime("demo-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)

    print(
        f"{env_config.n_pursuers} pursuers vs {env_config.n_evaders} evaders, "
        f"{demo.episodes} episodes per team (config: {args.config or 'embedded default'})"
    )
    print(f"{'team':<32} {'success':>15} {'collision':>15} {'length':>15}  wall")
    for team in demo.teams:
        policies = [make_policy(name, env_config) for name in team]
        start = time.perf_counter()
        s = rollout(env_config, policies, demo.episodes, seed=demo.seed).summary()
        wall = time.perf_counter() - start
        print(
            f"{' + '.join(team):<32} {s['success']:>7.1%} ± {s['success_se']:<5.1%} "
            f"{s['collision']:>7.1%} ± {s['collision_se']:<5.1%} "
            f"{s['length']:>7.1f} ± {s['length_se']:<5.1f}  {wall:.1f}s"
        )

    first = demo.teams[0]
    traj = record(env_config, [make_policy(n, env_config) for n in first], seed=demo.replay_seed)
    gif, png = out / "replay.gif", out / "trajectory.png"
    animate_trajectory(env_config, traj, str(gif))
    plot_trajectory(env_config, traj, str(png))
    (out / "config.yaml").write_text(
        yaml.safe_dump(
            {
                "env": env_config.to_dict(),
                "demo": {
                    "teams": [list(t) for t in demo.teams],
                    "episodes": demo.episodes,
                    "seed": demo.seed,
                    "replay_seed": demo.replay_seed,
                },
            },
            sort_keys=False,
        )
    )
    print(f"replay of {' + '.join(first)} (seed {demo.replay_seed}): {traj.metrics}")
    print(f"wrote {gif}, {png} and {out / 'config.yaml'}")


if __name__ == "__main__":
    main()
