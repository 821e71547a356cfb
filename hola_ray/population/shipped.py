"""Populations built once and shipped like the pools (contract §5): generation 0 of a run, its
files hashed in a manifest, adopted by any run whose layout it fits.

    pools/populations/<name>/
      manifest.json                 format hola_ray.population/1: what built it (commit,
                                    config, seed), the layout it fits, each member's files,
                                    sha256, role and its team figures as copies
      members/node_0000.pt          a member's plain-torch export (`MLPPolicy.load`)
      members/node_0000.rllib.pt    its RLlib module state (to seat it as a partner)
      generations/gen_0000/         generation 0 as the building run wrote it: G_0's
                                    hyperedge weights (edges.json), η, φ, state, metrics

The folder is laid out as a run directory's generation 0, so a run adopts it as it adopts
a sibling trial's (`RunDir.adopt_generation_zero`). Loading (`load`) verifies every file's
hash, refuses a population whose layout differs from the run's, one built by another
kind of pre-training than the run's method uses, and one that shares a file with a pool.
Building it is `python -m hola_ray populations` (`hola_ray/commands/populations.py`).
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hola_ray import homes
from hola_ray.evaluation.pools import pooled_files
from hola_ray.homes import MANIFEST, sha256
from hola_ray.population.rundir import RunDir

FORMAT = "hola_ray.population/1"
POPULATIONS_DIR = homes.POPULATIONS
NONE = "none"
"""`pretrain.population` when a run pre-trains its own generation 0"""


class PopulationError(RuntimeError):
    """A shipped population is missing, changed, or does not fit the run."""


def population_dir(
    population: str | Path, seed: int | None = None, kind: str | None = None
) -> Path:
    """A shipped population's folder: a name under pools/populations/ or a folder holding
    a manifest; `{seed}` in the name is the run's seed (one population per seed),
    `{seed%N}` the seed modulo N (N builds shared by the seeds: seeds 0 and 3 on build 0
    when N is 3) and `{kind}` the kind its method builds (mep, fcp, pbt: one experiment
    seats each method on its own kind of population)."""
    text = str(population)
    if seed is not None:
        text = text.replace("{seed}", str(seed))
        text = re.sub(r"\{seed%(\d+)\}", lambda m: str(seed % int(m[1])), text)
    if kind is not None and "{kind}" in text:
        text = text.replace("{kind}", kind)
    known = {name: POPULATIONS_DIR / name for name in names()}
    hint = " (build one with python -m hola_ray populations build)"
    return homes.artefact_dir(text, known, "no shipped population", PopulationError, hint)


def names() -> list[str]:
    """The populations shipped under pools/populations/, by name."""
    return sorted(p.name for p in POPULATIONS_DIR.glob("*") if (p / MANIFEST).is_file())


def package(
    run_dir: Path,
    out: Path,
    *,
    name: str,
    kind: str,
    layout: Mapping[str, Any],
    provenance: Mapping[str, Any],
    roles: Mapping[int, str],
    figures: Mapping[int, Mapping[str, float]],
    scenario: str,
) -> dict[str, Any]:
    """Copy generation 0 of `run_dir` (its members' files and its folder) to `out` and write
    the manifest: every file's sha256, each member's role and team figures as copies."""
    source = RunDir(run_dir)
    state = source.read_json(0, "state.json")
    nodes = sorted(int(v) for v in state["population"]["slots"].values())
    if set(nodes) != set(roles):
        raise PopulationError(f"{run_dir}: members {nodes}, roles given for {sorted(roles)}")
    if out.exists():
        shutil.rmtree(out)
    target = RunDir(out)
    target.members.mkdir(parents=True)
    shutil.copytree(source.generation(0), target.generation(0))
    members: dict[str, Any] = {}
    for v in nodes:
        export, state_file = source.member_export(v), source.member_state(v)
        for path in (export, state_file):
            shutil.copyfile(path, target.members / path.name)
        members[f"node_{v}"] = {
            "node": v,
            "file": f"members/{export.name}",
            "sha256": sha256(export),
            "state_file": f"members/{state_file.name}",
            "state_sha256": sha256(state_file),
            "scenario": scenario,
            "role": roles[v],
            **{f"team_{k}": x for k, x in figures[v].items()},
        }
    generation = {
        str(p.relative_to(out)): sha256(p)
        for p in sorted(target.generation(0).rglob("*"))
        if p.is_file()
    }
    manifest = {
        "format": FORMAT,
        "population": name,
        "kind": kind,
        **provenance,
        "layout": dict(layout),
        "members": members,
        "generation_files": generation,
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def read(folder: Path) -> dict[str, Any]:
    missing = f"not a shipped population (python -m hola_ray populations build {folder.name})"
    return homes.read_manifest(folder, FORMAT, PopulationError, missing)


def verify(folder: Path, manifest: Mapping[str, Any]) -> None:
    """Every file the manifest names is there with its sha256, or one clear error."""
    expected = dict(manifest["generation_files"])
    for entry in manifest["members"].values():
        expected[entry["file"]] = entry["sha256"]
        expected[entry["state_file"]] = entry["state_sha256"]
    homes.verify_files(folder, expected, f"population {folder.name}", PopulationError)


def check_layout(folder: Path, manifest: Mapping[str, Any], layout: Mapping[str, Any]) -> None:
    """The run seats these members only if it plays the same scenario size, observation,
    network, action distribution and proximity features."""
    shipped = manifest["layout"]
    differ = sorted(k for k in set(shipped) | set(layout) if shipped.get(k) != layout.get(k))
    if differ:
        said = "; ".join(f"{k} {shipped.get(k)!r}, the run's {layout.get(k)!r}" for k in differ)
        raise PopulationError(
            f"population {folder.name} does not fit this run ({said}); pre-train instead "
            "with pretrain.population: none"
        )


def check_apart_from_pools(folder: Path, manifest: Mapping[str, Any]) -> None:
    """No member file of the population is a pool member's (evaluation or validation)."""
    pooled = pooled_files()
    for mid, entry in manifest["members"].items():
        for key in ("sha256", "state_sha256"):
            if entry[key] in pooled:
                raise PopulationError(
                    f"population {folder.name}: member {mid} is pool member "
                    f"{pooled[entry[key]]}: a pool's teammates never enter training"
                )


def load(
    population: str | Path, seed: int, layout: Mapping[str, Any], kind: str | tuple[str, ...]
) -> tuple[RunDir, dict[str, Any]]:
    """A verified shipped population that fits the run: its folder as a run directory to
    adopt generation 0 from, and its manifest. `kind`: the kind the run's method builds
    (what `{kind}` in the name reads), or it and the others the method may seat."""
    kinds = (kind,) if isinstance(kind, str) else kind
    folder = population_dir(population, seed, kinds[0])
    manifest = read(folder)
    if manifest.get("kind") not in kinds:
        raise PopulationError(
            f"population {folder.name} was built by {manifest.get('kind')!r} pre-training; "
            f"this run's method builds {kinds[0]!r} populations (pre-train instead with "
            "pretrain.population: none)"
        )
    verify(folder, manifest)
    check_layout(folder, manifest, layout)
    check_apart_from_pools(folder, manifest)
    return RunDir(folder), manifest


def preferred_member(
    population: str | Path, seed: int, layout: Mapping[str, Any]
) -> tuple[RunDir, dict[str, Any], int, float]:
    """A shipped population's most preferred member, the highest η of its G_0 (the lowest
    node on a tie), verified as `load` verifies whatever its kind: where a method without a
    population of its own (self-play) starts its learner (`pretrain.learner_start: member`).
    Returns the folder as a run directory, its manifest, the node and its η."""
    folder = population_dir(population, seed)
    donor, manifest = load(folder, seed, layout, str(read(folder).get("kind")))
    eta = {int(v): float(x) for v, x in donor.read_json(0, "eta.json").items()}
    node = most_preferred(eta)
    return donor, manifest, node, eta[node]


def most_preferred(eta: Mapping[int, float | None]) -> int:
    """The node with the highest η (none counts as 0), the lowest node on a tie: the
    member a learner starts from with `pretrain.learner_start: member`."""
    return max(sorted(eta), key=lambda v: eta[v] or 0.0)
