"""Take a learner to a flight stack: `python -m hola_ray export POLICY --onnx OUT.onnx`.

POLICY is a run directory (its final learner.pt; `--best` takes best.pt), a generation
folder (`RUN/generations/gen_0008`), an export file (.pt) or a pool member id (ppo-1 …).
Writes the deterministic actor as ONNX (the raw observation in, the arena's action and the
heading change it commands out; the proximity features are inside the graph) and OUT.json
beside it: each observation entry (what it measures, frame, units, scale, the value when
unobserved), the action's meaning and bound, the speed and control period, the scenario,
and where it came from (run, generation, the commit that trained it, the sha256 of the
export and of the ONNX file). Then it checks the graph with onnxruntime against the torch
policy on observations of the scenario's own episodes and prints the largest difference.

Needs the deploy extra: pip install -e '.[deploy]'.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import PursuitConfig
from hola_ray.provenance import commit_id

INSTALL = "pip install -e '.[deploy]'"


def resolve(policy: str, best: bool = False) -> tuple[Any, dict[str, Any]]:
    """(MLPPolicy, source facts) of a run directory, generation folder, export file or pool
    member id."""
    from hola_ray.evaluation.pools import MEMBERS, POOLS, pool_dir, read_manifest
    from hola_ray.homes import sha256
    from hola_ray.policies.learned import MLPPolicy, manifest_scenario
    from hola_ray.policies.registry import load_export, policy_file

    path = Path(policy)
    source: dict[str, Any] = {"policy": policy, "exported_at_commit": commit_id()}
    if not path.exists() and policy in MEMBERS:
        pool = next(p for p, ids in POOLS.items() if policy in ids)
        folder = pool_dir(pool)
        pool_manifest = read_manifest(folder)
        entry = pool_manifest["members"][policy]
        if entry["kind"] != "ppo":
            raise ValueError(f"{policy} is a {entry['kind']} member: only MLP learners export")
        file = folder / entry["file"]
        env = dict(entry.get("config_values", {}).get("env") or entry["scenario"])
        config = PursuitConfig.from_dict(env)
        source |= {
            "pool": pool,
            "member": policy,
            "run": None,
            "generation": None,
            "commit": pool_manifest.get("commit"),
        }
    else:
        if not path.exists():
            raise ValueError(f"{policy}: no such run directory, generation folder or file")
        if path.is_dir() and best:
            file = path / "best.pt"
        else:
            file = policy_file(path)
        export = load_export(file)
        scenario = export.get("scenario") or manifest_scenario(file)
        if scenario is None:
            raise ValueError(
                f"{file} does not say which scenario it was trained in, and no manifest "
                "beside it lists it"
            )
        config = PursuitConfig.from_dict(scenario)
        source |= _run_facts(path, file) | {"commit": export.get("commit")}
    if not file.is_file():
        raise ValueError(f"{file}: no such file")
    policy_obj = MLPPolicy(config, load_export(file), name=file.stem)
    source |= {"file": str(file), "file_sha256": sha256(file)}
    return policy_obj, source


def _run_facts(path: Path, file: Path) -> dict[str, Any]:
    """The run directory and generation an export file belongs to, where its place says."""
    if path.is_dir() and path.parent.name == "generations":
        return {"run": str(path.parent.parent), "generation": int(path.name.split("_")[-1])}
    root = path if path.is_dir() else file.parent
    info = root / ("best.json" if file.name == "best.pt" else "learner.json")
    if info.is_file() and (root / "config.yaml").is_file():
        return {"run": str(root), "generation": json.loads(info.read_text()).get("generation")}
    return {"run": None, "generation": None}


def check(policy: Any, onnx_path: Path, episodes: int = 8, seed: int = 0) -> tuple[float, int]:
    """Largest |onnxruntime − MLPPolicy.act| over the observations of `episodes` episodes of
    the policy flying as the whole team in its own scenario; and how many it compared."""
    import numpy as np

    from hola_ray.evaluation.probe import reference_observations
    from hola_ray.policies.deploy import onnx_actions

    team = [policy] * policy.config.n_pursuers
    obs = reference_observations(policy.config, episodes, every=1, seed=seed, team=team)
    action, _ = onnx_actions(onnx_path, obs)
    return float(np.abs(action - policy.act(obs)).max()), int(obs.shape[0])


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m hola_ray export", description=__doc__)
    parser.add_argument("policy", help="run directory, generation folder, .pt file or member id")
    parser.add_argument("--onnx", type=Path, required=True, help="the ONNX file to write")
    parser.add_argument("--best", action="store_true", help="a run directory's best.pt")
    args = parser.parse_args(argv)
    if args.onnx.suffix != ".onnx":
        return fail(f"--onnx must name a .onnx file, got {args.onnx}")
    try:
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
    except ImportError as err:
        return fail(f"the export needs onnx and onnxruntime ({err.name} is missing): {INSTALL}")
    from hola_ray.policies.deploy import export_onnx, manifest, write_manifest

    try:
        policy, source = resolve(args.policy, args.best)
    except (ValueError, ConfigError, OSError) as err:
        return fail(str(err))
    onnx_path = export_onnx(policy, args.onnx)
    json_path = write_manifest(args.onnx.with_suffix(".json"), manifest(policy, onnx_path, source))
    worst, rows = check(policy, onnx_path)
    print(f"wrote {onnx_path} and {json_path}")
    print(
        f"onnxruntime against MLPPolicy.act on {rows} observations of its own scenario: "
        f"largest difference {worst:.2e}"
    )
    return 0


def script() -> None:
    """`hola-export` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
