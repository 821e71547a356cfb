"""The unseen teammate pools (docs/contract.md §3, paper Appendix) as this library loads them: the
members, the manifests and their hashes, and the validation set. Built by the command
`python -m hola_ray pools` (`hola_ray/commands/pools.py`).

A pool is a folder `pools/<name>/` holding one weights file per learned member and
`manifest.json`: per member its paper name, kind, file and the file's sha256, the config
and seed it was trained with, the commit that trained it, the scenario it plays, and its
paper Table II figures (three copies against one evader). Hand-written members (Greedy,
VICSEK) are code, so they have no file. Loading a pool checks every hash and refuses a
changed file, so an evaluation always plays the teammates the manifest describes.

No pool member is ever used in training: training and selection read the validation set
alone, through `load_validation`, which refuses any evaluation member (a test reads the
imports of hola_ray/methods, oracle and population).

A learned member trained for another team than a scenario's plays it through
`hola_ray.policies.adapter.ScenarioAdapter`: with fewer evaders, the missing ones read as
captured, (2, 0, 0), exactly what the member saw in training once an evader was caught
(that is how Table II's one-evader episodes are played by members trained for two); with
more teammates or evaders than it has slots for, it sees the nearest (contract §6.2).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hola_ray import homes
from hola_ray.config.scenario import PursuitConfig
from hola_ray.homes import MANIFEST
from hola_ray.policies.adapter import trained_scenario
from hola_ray.policies.base import Policy
from hola_ray.policies.registry import load_fitted, make_policy

POOLS_DIR = homes.POOLS
RUNS_DIR = homes.RUNS / "pools"
FORMAT = "hola_ray.pool/1"


@dataclass(frozen=True)
class Member:
    """A pool member: its paper name, how it is made, and (if trained) its config."""

    id: str
    name: str
    kind: str  # "handwritten" | "ppo" | "d3qn"
    config: str | None = None  # repository-relative path of the training config

    @property
    def file(self) -> str | None:
        return None if self.kind == "handwritten" else f"{self.id}.pt"


VALIDATION = "validation"
"""The validation teammates' pool: built only from what training may see."""

VALIDATION_MEMBERS = (
    Member("apf-a-3", "APF-A (λ 1.71 m, η 1e-3)", "handwritten"),
    Member("apf-a-9", "APF-A (λ 0.57 m, η 1e-2)", "handwritten"),
    Member("apf-a-21", "APF-A (λ 2.86 m, η 1e-1)", "handwritten"),
    Member("sp-v1", "SP (v1)", "ppo", "configs/pools/sp-v1.yaml"),
    Member("sp-v2", "SP (v2)", "ppo", "configs/pools/sp-v2.yaml"),
)
"""Validation teammates: three fixed APF-A pairs (DACOOP-A's potential field, which no
evaluation pool member plays as such: three copies, 3 vs 2, 60 episodes, reach 98 % success
with 12 % collision, 70 % and 10 % slowly, 60 % and 60 %) and two self-play agents of seeds
no evaluation member or training run uses. Disjoint from the evaluation pools by id and by file hash
(`load_validation` checks both)."""

SURROUND = "surround"
"""A validation set of a third kind: hand-written pursuers that neither evaluation pool holds and
that share nothing with the learned members (`hola_ray.policies.surround`)."""

SURROUND_SET = (
    Member("surround-1", "Surround (flank 1)", "handwritten"),
    Member("surround-2", "Surround (flank 1.5, wide)", "handwritten"),
    Member("surround-3", "Surround (flank 0.3)", "handwritten"),
)
"""Validation teammates that divide the evaders and close in from an uncovered side: no
self-play PPO from this code and no APF-A, so a method favoured by resembling either
evaluation pool is not favoured in selection (three copies, 3 vs 2, 300 episodes: 97 % success
with 2 % collision, 91 % with 41 %, 77 % with 3 %)."""


MEMBERS = {
    m.id: m
    for m in (
        Member("ppo-1", "PPO (1)", "ppo", "configs/pools/ppo-1.yaml"),
        Member("ppo-2", "PPO (2)", "ppo", "configs/pools/ppo-2.yaml"),
        Member("greedy", "Greedy", "handwritten"),
        Member("vicsek", "VICSEK", "handwritten"),
        Member("d3qn-g-1", "D3QN-G (1)", "d3qn", "configs/pools/d3qn-g-1.yaml"),
        Member("d3qn-g-2", "D3QN-G (2)", "d3qn", "configs/pools/d3qn-g-2.yaml"),
        *VALIDATION_MEMBERS,
        *SURROUND_SET,
    )
}
"""Every pool member by id."""

EVALUATION_POOLS = {
    "hot": ("ppo-1", "ppo-2"),
    "het": ("greedy", "vicsek", "d3qn-g-1", "d3qn-g-2"),
}
"""The zero-shot evaluation's pools (paper: homogeneous = PPO; heterogeneous = the rest):
used for the final figures alone, never in training, selection or tuning."""

POOLS = {
    **EVALUATION_POOLS,
    VALIDATION: tuple(m.id for m in VALIDATION_MEMBERS),
    SURROUND: tuple(m.id for m in SURROUND_SET),
}
"""Pool name → member ids: the evaluation pools and the validation sets."""


class PoolError(RuntimeError):
    """A pool that cannot be used as it is: unknown, unbuilt, or changed since its build."""


# ---- manifests and hashes -------------------------------------------------------------------
def pool_dir(pool: str | Path) -> Path:
    """`hot`, `het` or a folder holding a manifest → the pool's folder."""
    known = {name: POOLS_DIR / name for name in POOLS}
    return homes.artefact_dir(pool, known, "unknown pool", PoolError)


def read_manifest(folder: Path) -> dict[str, Any]:
    missing = f"build it with python -m hola_ray pools build --pool {folder.name}"
    return homes.read_manifest(folder, FORMAT, PoolError, missing)


def verify(folder: Path, manifest: dict[str, Any]) -> None:
    """Every member file is there and has the manifest's sha256, or one clear error."""
    expected = {e["file"]: e["sha256"] for e in manifest["members"].values() if e.get("file")}
    homes.verify_files(folder, expected, f"pool {folder.name}", PoolError)


def load_member(folder: Path, mid: str, entry: dict[str, Any], config: PursuitConfig) -> Policy:
    """One verified member as a policy for the scenario `config`."""
    kind = entry["kind"]
    if kind == "handwritten":
        return make_policy(mid, config)
    scenario = entry["scenario"]
    if kind not in ("ppo", "d3qn"):
        raise PoolError(f"pool {folder.name}: member {mid} has an unknown kind {kind!r}")
    # D3QN-G reads the first evader only and plays Greedy once it is caught (contract §3):
    # it plays any number of evaders as it is (`load_fitted`)
    trained = trained_scenario(config, scenario["n_pursuers"], scenario["n_evaders"])
    try:
        return load_fitted(folder / entry["file"], config, trained, name=entry["name"])
    except ValueError as err:
        raise PoolError(f"pool {folder.name}: member {mid}: {err}") from err


def load_validation(pool: str | Path, config: PursuitConfig) -> dict[str, Policy]:
    """The validation teammates (`VALIDATION` or a folder with a manifest) for `config`'s
    scenario, every file verified; refused when it shares a member id or a file with an
    evaluation pool, so no evaluation teammate can enter training, selection or tuning."""
    if str(pool) in EVALUATION_POOLS:
        raise PoolError(f"{pool} is an evaluation pool: it never validates training")
    folder = pool_dir(pool)
    manifest = read_manifest(folder)
    held_out = {mid for ids in EVALUATION_POOLS.values() for mid in ids}
    hashes = pooled_files(EVALUATION_POOLS)
    for mid, entry in manifest["members"].items():
        if mid in held_out:
            raise PoolError(f"{folder}: member {mid} belongs to an evaluation pool")
        if entry.get("sha256") in hashes:
            raise PoolError(f"{folder}: member {mid}'s file is an evaluation pool member's")
    return load_pool(folder, config)


def pooled_files(pools: Iterable[str] = POOLS) -> dict[str, str]:
    """sha256 → "pool/member" of every committed member file of `pools` (default: the
    evaluation pools and the validation set): files training never takes in as its own."""
    out: dict[str, str] = {}
    for name in pools:
        if (POOLS_DIR / name / MANIFEST).is_file():
            for mid, entry in read_manifest(POOLS_DIR / name)["members"].items():
                if entry.get("sha256"):
                    out[entry["sha256"]] = f"{name}/{mid}"
    return out


def validation_mates(config: PursuitConfig, count: int) -> list[Policy]:
    """The first `count` validation members in name order: the fixed teammates the probes
    and `benchmarks/crashes.py` seat beside a learner."""
    members = load_validation(VALIDATION, config)
    return [members[k] for k in sorted(members)][:count]


def load_pool(pool: str | Path, config: PursuitConfig) -> dict[str, Policy]:
    """A pool's members (id → policy for the scenario `config`), every file verified."""
    folder = pool_dir(pool)
    manifest = read_manifest(folder)
    verify(folder, manifest)
    return {
        mid: load_member(folder, mid, entry, config) for mid, entry in manifest["members"].items()
    }
