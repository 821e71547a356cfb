"""Competent populations, built once and shipped like the pools (docs/contract.md §5).

    python -m hola_ray populations build NAME [--episodes 500] [--quiet] [--carry]
    python -m hola_ray populations show [NAME]

`build` trains generation 0 of `configs/populations/NAME.yaml` (a run config with
`generations: 0`: MEP's members until each is competent as a team of its own copies, or
FCP's self-play agents with their checkpoints) in `runs/populations/NAME` (a stopped build
resumes there), plays every member as a team of its own copies on `--episodes` episodes,
and writes `pools/populations/NAME/`: the members' exports and RLlib states, generation 0
(G_0's hyperedge weights in `edges.json`) and a manifest with every file's sha256, each
member's role and team figures, and the commit, config and seed that built it. A run takes
it with `pretrain.population: NAME` (`{seed}` in the name is the run's seed); what loading
checks is `hola_ray.population.shipped`. `show` verifies and prints them.

A build that outlasts its machine: with `--carry`, every check a build saves (its members
and progress, `RunDir.save_pretrain`) is mirrored to `pools/builds/NAME/`, a few hundred kB
to commit, and a build that finds there a later check than its own run directory's starts
from it; once the population is shipped the carried check is removed.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import threading
from pathlib import Path
from typing import Any

from hola_ray import homes
from hola_ray.cli import OneLineParser, fail
from hola_ray.homes import ROOT
from hola_ray.population.shipped import (
    POPULATIONS_DIR,
    PopulationError,
    names,
    package,
    population_dir,
    read,
    verify,
)
from hola_ray.provenance import commit_id

CONFIGS = homes.CONFIGS / "populations"
RUNS = homes.RUNS / "populations"
BUILDS = homes.POOLS / "builds"
"""where `build --carry` keeps each build's last check, to commit between machines"""
PROGRESS = "progress.json"
BARS = {"3v1": (0.85, 0.15), "3v2": (0.60, 0.35)}
"""contract §5.1: a learned member as a team of its own copies succeeds at least, and collides
at most, this often (per scenario)"""
JUDGED = ("member", "checkpoint-end")
"""the roles held to the bar: MEP's members and FCP's end checkpoints (a start checkpoint is
random weights, FCP's weakest partner on purpose)"""
FIGURES_SEED = 9_100_000
"""the run seed of the episodes each member is judged on as a team of its own copies"""


def team_figures(config: Any, export: dict[str, Any], episodes: int) -> dict[str, float]:
    """A member as a team of its own copies: success and collision, and the episodes and
    seed they were measured on (what a test replays)."""
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.policies.learned import MLPPolicy

    env = config.env.judged()  # a team that changes: the contract's 3-pursuer bar (§5.1)
    team = [MLPPolicy(env, export)] * env.n_pursuers
    played = rollout(env, team, episodes, seed=FIGURES_SEED)
    return {
        "success": round(float(played.success.mean()), 4),
        "collision": round(float(played.collision.mean()), 4),
        "episodes": episodes,
        "seed": FIGURES_SEED,
    }


def below_bar(figures: dict[int, dict[str, float]], roles: dict[int, str], scenario: str) -> str:
    """The members held to the contract's bar (`JUDGED`) that miss it, said in one line; "" when
    none does."""
    success, collision = BARS[scenario]
    missed = [
        f"node {v} ({f['success']:.1%} success, {f['collision']:.1%} collision)"
        for v, f in sorted(figures.items())
        if roles[v] in JUDGED and (f["success"] < success or f["collision"] > collision)
    ]
    if not missed:
        return ""
    return (
        f"NOT at the contract's {scenario} bar (as copies: success >= {success:.0%}, collision <= "
        f"{collision:.0%}): " + ", ".join(missed)
    )


def checked_env_steps(folder: Path) -> int:
    """The env steps of the check saved in `folder` (a run's `pretrain/` or a carried
    build), -1 where there is none."""
    path = folder / PROGRESS
    return int(json.loads(path.read_text())["env_steps"]) if path.is_file() else -1


def copy_check(source: Path, target: Path) -> bool:
    """Copy the check in `source` to `target` when `target` has none or an earlier one: the
    members' arrays first, each written whole, and the progress that names them last, so a
    copy stopped part way leaves the earlier check whole. True when it copied."""
    if checked_env_steps(source) <= checked_env_steps(target):
        return False
    progress = (source / PROGRESS).read_text()
    target.mkdir(parents=True, exist_ok=True)
    for mid in json.loads(progress)["members"]:
        shutil.copyfile(source / f"{mid}.npz", target / f".tmp_{mid}.npz")
        os.replace(target / f".tmp_{mid}.npz", target / f"{mid}.npz")
    (target / f".tmp_{PROGRESS}").write_text(progress)
    os.replace(target / f".tmp_{PROGRESS}", target / PROGRESS)
    return True


class Carry:
    """`build --carry`: the run's `pretrain/` check mirrored to `pools/builds/NAME/` from a
    thread, polled every `every` seconds and once more at the end."""

    def __init__(self, name: str, pretrain: Path, every: float = 5.0) -> None:
        self.name, self.pretrain, self.folder = name, pretrain, BUILDS / name
        self.every, self.stop = every, threading.Event()
        self.thread = threading.Thread(target=self.watch, name="carry", daemon=True)

    def restore(self) -> None:
        """Start from the carried check where it is later than the run directory's."""
        if copy_check(self.folder, self.pretrain):
            print(
                f"[{self.name}] resuming from the carried check at "
                f"{checked_env_steps(self.pretrain):,} env steps ({self.folder})",
                flush=True,
            )

    def mirror(self) -> None:
        if copy_check(self.pretrain, self.folder):
            print(
                f"[{self.name}] check at {checked_env_steps(self.folder):,} env steps carried "
                f"to {self.folder} (commit it to keep it past this machine)",
                flush=True,
            )

    def watch(self) -> None:
        while not self.stop.wait(self.every):
            self.mirror()

    def __enter__(self) -> Carry:
        self.restore()
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()
        self.mirror()

    def shipped(self) -> None:
        """The population is packaged: its carried check has served."""
        if self.folder.is_dir():
            shutil.rmtree(self.folder)
            print(f"[{self.name}] the build is shipped: {self.folder} removed", flush=True)


def build(name: str, episodes: int, progress: bool = True, carry: bool = False) -> Path:
    """Train (or resume) generation 0 of the population's config, then package it; with
    `carry`, its checks mirrored to and resumed from `pools/builds/NAME/` (`Carry`)."""
    import ray

    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.trainer import Trainer
    from hola_ray.population.rundir import RunDir
    from hola_ray.process import NAMESPACE, init_local_ray

    path = CONFIGS / f"{name}.yaml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in CONFIGS.glob("*.yaml"))) or "(none)"
        raise PopulationError(f"no population config {path}; the configs: {known}")
    config = RunConfig.from_yaml(path)
    if config.generations != 0 or config.strategy.origin.kind is None:
        raise PopulationError(
            f"{path}: a population config trains generation 0 only (generations: 0) of a "
            "method with a population"
        )
    if not ray.is_initialized():
        init_local_ray(namespace=NAMESPACE)
    run = RunDir(RUNS / name)
    carried = Carry(name, run.pretrain) if carry else None
    if carried is None:
        Trainer(config, run.root, progress=progress).fit()
    else:
        with carried:
            Trainer(config, run.root, progress=progress).fit()
    state = run.read_json(0, "state.json")
    nodes = sorted(int(v) for v in state["population"]["slots"].values())
    figures = {}
    for v in nodes:
        figures[v] = team_figures(config, run.load_member_export(v), episodes)
        print(
            f"[{name}] node {v}: as {config.env.judged().n_pursuers} copies, success "
            f"{figures[v]['success']:.1%}, collision {figures[v]['collision']:.1%}",
            flush=True,
        )
    gen0 = run.metrics(0)
    roles = config.strategy.member_roles(nodes)
    judged = config.env.judged()
    scenario = f"{judged.n_pursuers}v{judged.n_evaders}"
    kept = (
        "pretrain_env_steps",
        "pretrain_s",
        "pretrain_competent",
        "pretrain_members_from_env_steps",
    )
    built = {k: gen0[k] for k in kept if k in gen0}
    if run.pretrain.joinpath(PROGRESS).is_file():  # every check, the deciding one included
        built["checks"] = json.loads(run.pretrain.joinpath(PROGRESS).read_text()).get("checks", [])
    out = POPULATIONS_DIR / name
    package(
        run.root,
        out,
        name=name,
        kind=config.strategy.origin.kind,
        layout=config.layout(),
        provenance={
            "commit": commit_id(),
            "config": str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path),
            "config_values": config.to_dict(),
            "seed": config.seed,
            "method": config.method,
            "built": built,
        },
        roles=roles,
        figures=figures,
        scenario=scenario,
    )
    missed = below_bar(figures, roles, scenario)
    said = missed or f"every judged member at the contract's {scenario} bar"
    print(f"[{name}] {said}", flush=True)
    if carried is not None:
        carried.shipped()
    return out


def building() -> list[str]:
    """The builds in progress whose check is carried under pools/builds/, by name."""
    return sorted(p.parent.name for p in BUILDS.glob(f"*/{PROGRESS}"))


def show_build(name: str, last: int = 5) -> str:
    """A build in progress from its carried check: its env steps against its cap, and its
    `last` checks, each member as a team of its own copies against the figures the build
    stops at."""
    from hola_ray.methods.config import RunConfig

    progress = json.loads((BUILDS / name / PROGRESS).read_text())
    pre = RunConfig.from_yaml(CONFIGS / f"{name}.yaml").pretrain
    lines = [
        f"build {name} in progress (its check in {BUILDS / name}): {progress['env_steps']:,} "
        f"env steps of its {pre.env_steps:,} cap; it stops once every member as copies "
        f"succeeds >= {pre.until_success:.0%} and collides <= {pre.until_collision:.0%}, "
        f"{pre.until_in_a_row} checks in a row",
        f"  {'env steps':>12}  {'success %, each member':<24} {'collision %':<24} at the bar",
    ]
    for check in progress["checks"][-last:]:
        ok = sum(
            a >= pre.until_success and c <= pre.until_collision
            for a, c in zip(check["success"], check["collision"], strict=True)
        )
        success = " ".join(f"{100 * x:3.0f}" for x in check["success"])
        collision = " ".join(f"{100 * x:3.0f}" for x in check["collision"])
        lines.append(
            f"  {check['env_steps']:>12,}  {success:<24} {collision:<24} "
            f"{ok} of {len(check['success'])}"
        )
    return "\n".join(lines)


def _started_from(manifest: dict[str, Any]) -> str:
    """ ", its members started from X's (N env steps)" for a build with `pretrain.members_from`."""
    named = manifest.get("config_values", {}).get("pretrain", {}).get("members_from", "none")
    if named == "none":
        return ""
    before = manifest.get("built", {}).get("pretrain_members_from_env_steps")
    known = isinstance(before, (int, float)) and math.isfinite(before)
    said = f" ({before:,.0f} env steps)" if known else ""
    return f", its members started from {Path(named).name}'s{said}"


def show(population: str | Path) -> str:
    folder = population_dir(population)
    manifest = read(folder)
    verify(folder, manifest)
    built = manifest.get("built", {})
    lines = [
        f"population {manifest['population']} ({folder}): {manifest['kind']}, "
        f"{len(manifest['members'])} members, seed {manifest['seed']}, built at commit "
        f"{str(manifest['commit'])[:12]} from {manifest['config']}"
        + (f", {built['pretrain_env_steps']:,} env steps" if "pretrain_env_steps" in built else "")
        + _started_from(manifest)
    ]
    for mid, e in manifest["members"].items():
        lines.append(
            f"  {mid:<8} {e['role']:<18} {e['scenario']}  as copies: success "
            f"{e['team_success']:.1%}, collision {e['team_collision']:.1%} "
            f"({e['team_episodes']} episodes); {e['file']} sha256 {e['sha256'][:12]}…"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(
        prog="python -m hola_ray populations", description=__doc__.split("\n\n")[0]
    )
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="train generation 0 of configs/populations/NAME.yaml")
    b.add_argument("name")
    b.add_argument("--episodes", type=int, default=500, help="episodes per member as copies")
    b.add_argument("--quiet", action="store_true")
    b.add_argument(
        "--carry",
        action="store_true",
        help="mirror each check to pools/builds/NAME (commit it) and resume from it",
    )
    s = sub.add_parser(
        "show", help="a shipped population's members, roles and figures, or a build's checks"
    )
    s.add_argument("name", nargs="?", default=None, help="default: every one, shipped or building")
    args = parser.parse_args(argv)
    try:
        if args.command == "build":
            folder = build(args.name, args.episodes, not args.quiet, args.carry)
            print(f"population {args.name} written to {folder}")
            print(show(folder))
        elif args.name in building() and args.name not in names():
            print(show_build(args.name))
        else:
            shown = [args.name] if args.name else names()
            if not shown:
                print(f"no population shipped in {POPULATIONS_DIR} yet")
            for n in shown:
                print(show(n))
            for n in building() if args.name is None else ():
                print(show_build(n))
    except PopulationError as err:
        return fail(str(err))
    return 0


def script() -> None:
    """`hola-populations` (`[project.scripts]`): `main` under the fixed hash seed."""
    from hola_ray.process import fixed_hash_seed, leave, pause_collector

    fixed_hash_seed("hola_ray.commands.populations", sys.argv[1:])
    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
