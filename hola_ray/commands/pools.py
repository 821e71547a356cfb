"""The unseen teammate pools (contract §3, paper Appendix): trained once, committed, verified.

    python -m hola_ray pools build [--pool hot|het|validation] [--episodes 50] [--seeds 0 1 2]
    python -m hola_ray pools show [--pool hot|het|validation]
    python -m hola_ray pools reference [--handwritten NAME ...] [--learned FILE ...]

This is the command that builds and shows the pools; what a pool is, and how it is loaded
and verified, is `hola_ray.evaluation.pools`.

- `hot` (homogeneous): PPO (1) and PPO (2), self-play PPO (`method: sp`) trained on the
  evaluation's scenario, 3 pursuers vs 2 evaders (configs/pools/ppo-*.yaml). The run
  directories stay under runs/pools/ (a build resumes or reuses them); the member is the
  run's best generation (`best.pt`, judged in self-play on its own scenario).
- `het` (heterogeneous): Greedy, VICSEK, D3QN-G (1) and (2).
- `validation`: the teammates training may see, for selection (APF-A pairs and two SP
  agents). The pool seeds (101, 102, …) are kept apart from the seeds of training runs.
- `reference` (not a pool: the learner's scale, `hola_ray.evaluation.scale`): the floor
  seat and the ceilings, each ceiling the candidate that does best with the validation
  teammates at 3 vs 2 (default candidates: every hand-written pursuer that is no evaluation
  pool member; learned candidates are files you name).
"""

from __future__ import annotations

import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import (
    EVALUATION_POOLS,
    FORMAT,
    MANIFEST,
    MEMBERS,
    POOLS,
    POOLS_DIR,
    RUNS_DIR,
    Member,
    PoolError,
    load_pool,
    pool_dir,
    read_manifest,
    verify,
)
from hola_ray.homes import ROOT, sha256
from hola_ray.provenance import commit_id


# ---- building -------------------------------------------------------------------------------
def train_member(member: Member, progress: bool = True) -> tuple[Path, dict[str, Any]]:
    """Train (or resume, or reuse) a learned member; its export file and build facts."""
    config_path = ROOT / member.config
    out = RUNS_DIR / member.id
    if member.kind == "ppo":
        from hola_ray.methods.config import RunConfig

        config = RunConfig.from_yaml(config_path)
        import ray

        from hola_ray.methods.trainer import Trainer
        from hola_ray.process import NAMESPACE, init_local_ray

        if not ray.is_initialized():
            init_local_ray(namespace=NAMESPACE)
        Trainer(config, out, progress=progress).fit()
        best = json.loads((out / "best.json").read_text())
        facts = {"generation": best["generation"], "env_steps": best["env_steps"]}
        return out / "best.pt", facts
    if member.kind == "d3qn":
        from hola_ray.oracle.d3qn_train import train_d3qn

        return train_d3qn(config_path, out, progress=progress)
    raise PoolError(f"{member.id} is not trained")


def member_config(member: Member):
    """A learned member's training config (`RunConfig` or `D3QNRun`): seed, env, values."""
    if member.kind == "d3qn":
        from hola_ray.oracle.d3qn_train import D3QNRun

        return D3QNRun.from_yaml(ROOT / member.config)
    from hola_ray.methods.config import RunConfig

    return RunConfig.from_yaml(ROOT / member.config)


def build(pool: str, episodes: int, seeds: Sequence[int], progress: bool = True) -> Path:
    """Train what the pool lacks, copy the members in, measure Table II, write the manifest."""
    from hola_ray.evaluation.table import measure

    folder = POOLS_DIR / pool
    folder.mkdir(parents=True, exist_ok=True)
    members: dict[str, Any] = {}
    for mid in POOLS[pool]:
        member = MEMBERS[mid]
        entry: dict[str, Any] = {"name": member.name, "kind": member.kind, "file": member.file}
        if member.kind != "handwritten":
            print(f"[{pool}] {member.name}: training or reusing {RUNS_DIR / mid}", flush=True)
            source, facts = train_member(member, progress)
            target = folder / member.file
            target.write_bytes(source.read_bytes())
            config = member_config(member)
            entry |= {
                "sha256": sha256(target),
                "config": member.config,
                "config_values": config.to_dict(),
                "seed": config.seed,
                "scenario": {
                    "n_pursuers": config.env.n_pursuers,
                    "n_evaders": config.env.n_evaders,
                },
                "trained": facts,
            }
        members[mid] = entry
    manifest = {"format": FORMAT, "pool": pool, "commit": commit_id(), "members": members}
    # written now so that Table II plays the members through the verified load path, and
    # again below with their Table II figures
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    # Table II: three copies against one evader, through the verified load path
    scenario = dataclasses.replace(PursuitConfig(), n_evaders=1)
    policies = load_pool(folder, scenario)
    for mid, policy in policies.items():
        row = measure(policy, scenario, episodes, seeds)
        members[mid]["table_ii"] = {
            k: round(v, 4) for k, v in row.items() if k in TABLE_II_KEYS
        } | {"episodes": len(seeds) * episodes, "seeds": list(seeds)}
        print(
            f"[{pool}] {members[mid]['name']}: Table II success {row['success']:.1%}, "
            f"length {row['length']:.1f}, collision {row['collision']:.1%}",
            flush=True,
        )
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return folder


TABLE_II_KEYS = ("success", "success_se", "length", "length_se", "collision", "collision_se")


def show(pool: str | Path) -> str:
    folder = pool_dir(pool)
    manifest = read_manifest(folder)
    verify(folder, manifest)
    lines = [f"pool {manifest['pool']} ({folder}), built at commit {manifest['commit'][:12]}"]
    for _mid, e in manifest["members"].items():
        t = e.get("table_ii", {})
        figures = (
            f"Table II success {t['success']:.1%}, length {t['length']:.1f}, "
            f"collision {t['collision']:.1%}"
            if t
            else "no Table II figures"
        )
        origin = (
            "hand-written"
            if e["kind"] == "handwritten"
            else f"{e['file']} sha256 {e['sha256'][:12]}…, seed {e['seed']}"
        )
        lines.append(f"  {e['name']:<11} {origin}; {figures}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m hola_ray pools", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="train what is missing and write pools/<name>/")
    b.add_argument("--pool", choices=sorted(POOLS), action="append", help="default: both")
    b.add_argument("--episodes", type=int, default=50, help="Table II episodes per seed")
    b.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    b.add_argument("--quiet", action="store_true")
    s = sub.add_parser("show", help="a pool's members, hashes and Table II figures")
    s.add_argument("--pool", default=None, help="hot, het or a folder (default: both)")
    r = sub.add_parser("reference", help="choose the learner's scale's ceilings on validation")
    r.add_argument("--handwritten", nargs="+", default=None, help="default: all but pool members")
    r.add_argument("--learned", nargs="+", type=Path, default=[], help="exported learners")
    r.add_argument("--episodes", type=int, default=100, help="validation episodes per seed")
    r.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    args = parser.parse_args(argv)
    try:
        if args.command == "reference":
            from hola_ray.evaluation.scale import write_reference
            from hola_ray.policies.registry import policy_names

            held_out = {mid for ids in EVALUATION_POOLS.values() for mid in ids}
            names = args.handwritten or [
                n for n in policy_names() if n not in held_out and n != "hold"
            ]
            write_reference(
                PursuitConfig(n_evaders=2), names, args.learned, args.episodes, args.seeds
            )
            return 0
        if args.command == "build":
            for pool in args.pool or sorted(POOLS):
                folder = build(pool, args.episodes, args.seeds, not args.quiet)
                print(f"pool {pool} written to {folder}")
        else:
            for pool in [args.pool] if args.pool else sorted(POOLS):
                print(show(pool))
    except PoolError as err:
        return fail(str(err))
    return 0


def script() -> None:
    """`hola-pools` (`[project.scripts]`): `main` under the fixed hash seed, as `python -m
    hola_ray.pools` runs it (`hola_ray.process.fixed_hash_seed`)."""

    from hola_ray.process import fixed_hash_seed, leave, pause_collector

    fixed_hash_seed("hola_ray.commands.pools", sys.argv[1:])
    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
