"""Where hola_ray keeps its artefacts: the repository root, defined once, and the homes
under it; the one lookup of an artefact by name or folder (`artefact_dir`: pools, the
validation set, shipped populations); and the one reader and verifier of the manifests
that pools and shipped populations carry (`read_manifest`, its lenient `manifest_or_none`,
`manifest_sha256`, `verify_files`).

Committed artefacts live under the repository: the teammate pools in `pools/`, the shipped
partner populations in `pools/populations/`, the configs that built them in `configs/`.
Every command writes its work under `runs/` in the current directory (`RUNS`) unless told
where (`--out`): a run, an evaluation, an experiment, and the training of a pool's or a
population's build, which then ships its result into the repository.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
"""the repository (or source tree) holding the package"""
CONFIGS = ROOT / "configs"
POOLS = ROOT / "pools"
"""the committed teammate pools, one folder each with its manifest"""
POPULATIONS = POOLS / "populations"
"""the committed partner populations, one folder each with its manifest"""
RUNS = Path("runs")
"""where every command writes by default: `runs/` in the current directory"""
MANIFEST = "manifest.json"
GENERATION_STATE = "learner.rllib.pt"
"""in a run's generation folder: the learner's RLlib module state (what a resume loads)"""
GENERATION_EXPORT = "learner.pt"
"""in a run's generation folder: the learner's plain-torch export (what is played)"""


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def artefact_dir(
    item: str | Path,
    known: Mapping[str, Path],
    what: str,
    error: type[Exception],
    hint: str = "",
) -> Path:
    """An artefact's folder: a name of `known` (name → its folder), or a folder holding a
    manifest; else one `error` saying "`what` 'item': give one of …", `hint` after it (how
    to build one). Only a `str` is taken for a name; a `Path` is a folder."""
    if isinstance(item, str) and item in known:
        return known[item]
    folder = Path(item)
    if (folder / MANIFEST).is_file():
        return folder
    raise error(
        f"{what} {str(item)!r}: give one of {', '.join(known) or '(none built)'} "
        f"or a folder with a {MANIFEST}{hint}"
    )


def manifest_sha256(folder: Path) -> str:
    """The sha256 of `folder`'s manifest: the artefact's fingerprint, since the manifest holds
    the sha256 of every file of it (changes with any rebuild)."""
    return sha256(folder / MANIFEST)


def manifest_or_none(folder: Path) -> dict[str, Any] | None:
    """`folder`'s manifest, of any format, or None where there is none, it cannot be read or
    it is no JSON object: for a question a manifest may answer (which scenario a member file
    was trained in), never a check (`read_manifest`)."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return manifest if isinstance(manifest, dict) else None


def read_manifest(folder: Path, fmt: str, error: type[Exception], missing: str) -> dict[str, Any]:
    """`folder`'s manifest of format `fmt`, or one `error` saying what is wrong with it;
    `missing`: what to do when there is none."""
    path = folder / MANIFEST
    if not path.is_file():
        raise error(f"{folder} holds no {MANIFEST}: {missing}")
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise error(f"{path}: not valid JSON ({err}); restore it from git") from err
    except OSError as err:
        raise error(f"{path}: cannot be read ({err})") from err
    if not isinstance(manifest, dict) or manifest.get("format") != fmt:
        got = manifest.get("format") if isinstance(manifest, dict) else None
        raise error(f"{path}: not a {fmt} manifest (format {got!r})")
    return manifest


def verify_files(
    folder: Path, expected: Mapping[str, str], what: str, error: type[Exception]
) -> None:
    """Every file of `expected` (path relative to `folder` → sha256) is there with its
    digest, or one `error` naming it; `what`: the artefact, as "pool hot"."""
    for relative, digest in sorted(expected.items()):
        path = folder / relative
        if not path.is_file():
            raise error(f"{what}: {path} is missing")
        got = sha256(path)
        if got != digest:
            raise error(
                f"{what}: {path} has sha256 {got[:12]}…, the manifest says {digest[:12]}…: "
                f"the file changed after the build; restore it (git checkout {path}) or "
                f"rebuild it"
            )
