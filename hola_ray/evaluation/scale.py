"""The learner's scale (docs/contract.md §5): reference seats played on the learner's own episodes.

A zero-shot figure has a floor set by the teammates: at 3 vs 2 with the HeT pool a seat
that holds its heading, and crashes in nearly every episode, still scores about half the
episodes, because two teammates often catch both evaders alone. So every evaluation plays
the same episodes (the same seeds, seats and drawn teammates) with reference seats in the
learner's place:

- the floor: `hold` (`hola_ray.policies.hold.HoldHeading`), a seat that does nothing useful;
- the ceilings: the strongest pursuers the project has, one hand-written and one learned,
  each chosen on the validation teammates (never an evaluation pool) by the rule of
  `choose`, and named in the committed manifest `pools/reference/manifest.json` (the learned
  one's file beside it, its hash checked on load);

and reports the learner's normalised score (learner − floor) / (ceiling − floor) of success
per ceiling, with a 95 % interval from the evaluation's stratified bootstrap
(`hola_ray.evaluation.compare`: the episodes resampled within each partner combination, the
same draw for the learner and the references, so their shared noise cancels). 1 is the
ceiling's level, 0 the floor's.

The manifest is written by `python -m hola_ray pools reference` from its candidates' figures;
nothing else writes it.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray import homes
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.compare import figures
from hola_ray.evaluation.pools import POOLS_DIR, PoolError, load_validation
from hola_ray.evaluation.teams import play
from hola_ray.policies.adapter import trained_scenario
from hola_ray.policies.base import Policy
from hola_ray.policies.registry import load_fitted, load_policy, make_policy
from hola_ray.provenance import commit_id

REFERENCE_DIR = POOLS_DIR / "reference"
FORMAT = "hola_ray.reference/1"
FLOOR = "floor"
"""the reference name of the floor seat"""
FLOOR_POLICY = "hold"
CEILINGS = ("handwritten", "learned")
"""the reference names of the ceilings, the first the headline's"""


# ---- the reference seats --------------------------------------------------------------------
def load_references(config: PursuitConfig, folder: Path = REFERENCE_DIR) -> dict[str, Policy]:
    """The floor and the ceilings for `config`'s scenario (reference name → policy), every
    file verified. A learned ceiling trained for another team size is left out (the
    hand-written one plays any)."""
    manifest = homes.read_manifest(
        folder, FORMAT, PoolError, "choose them with python -m hola_ray pools reference"
    )
    files = {
        e["file"]: e["sha256"] for e in manifest["ceilings"].values() if e.get("file") is not None
    }
    homes.verify_files(folder, files, "the reference seats", PoolError)
    out: dict[str, Policy] = {FLOOR: make_policy(manifest["floor"]["policy"], config)}
    for name in CEILINGS:
        entry = manifest["ceilings"].get(name)
        if entry is None:
            continue
        if entry.get("file") is None:
            out[name] = make_policy(entry["policy"], config)
            continue
        scenario = entry["scenario"]
        sizes = (scenario["n_pursuers"], scenario["n_evaders"])
        if sizes != (config.n_pursuers, config.n_evaders):
            continue
        trained = trained_scenario(config, *sizes)  # observed in other slots: adapted
        out[name] = load_fitted(folder / entry["file"], config, trained, entry["name"])
    return out


def reference_figures(played: Mapping[str, np.ndarray]) -> dict[str, float]:
    """A seat's success, collision and own crash on the evaluation's episodes
    (`hola_ray.evaluation.compare.figures`)."""
    point = figures(played)
    return {m: round(point[m], 4) for m in ("success", "collision", "learner_crash")}


def play_references(
    references: Mapping[str, Policy],
    members: list,
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
) -> dict[str, dict[str, np.ndarray]]:
    """Each reference seat's episodes with `members` (`hola_ray.evaluation.teams.play`):
    the learner's episodes, played once per pool and shared by every learner."""
    return {
        name: play(policy, members, config, episodes, seeds) for name, policy in references.items()
    }


def reference_fingerprint(folder: Path = REFERENCE_DIR) -> str | None:
    """The sha256 of the references' manifest (None without one): an evaluation cached
    under one fingerprint is played again once the references change."""
    path = folder / homes.MANIFEST
    return homes.sha256(path) if path.is_file() else None


# ---- choosing the ceilings ------------------------------------------------------------------
def validation_record(
    policy: Policy, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> dict[str, float]:
    """A candidate seat's figures with the validation teammates (success, collision, its
    own crash) and its rule score: success − own crash."""
    mates = list(load_validation("validation", config).values())
    played = play(policy, mates, config, episodes, seeds)
    record = reference_figures(played)
    record["score"] = round(record["success"] - record["learner_crash"], 4)
    return record


def choose(records: Mapping[str, Mapping[str, float]]) -> str:
    """The rule: the candidate with the highest validation success less its own crash rate
    (a ceiling both catches and survives); ties to the first named."""
    return max(records, key=lambda name: records[name]["score"])


def write_reference(
    config: PursuitConfig,
    handwritten: Sequence[str],
    learned: Sequence[Path],
    episodes: int = 100,
    seeds: Sequence[int] = (0, 1, 2),
    folder: Path = REFERENCE_DIR,
    say=print,
) -> Path:
    """Play every candidate with the validation teammates, choose each ceiling by `choose`
    and write the manifest (the learned ceiling's file copied beside it)."""
    import torch

    start = time.perf_counter()
    hand = {
        name: validation_record(make_policy(name, config), config, episodes, seeds)
        for name in handwritten
    }
    for name, record in hand.items():
        say(f"hand-written {name}: {record}")
    mine = {}
    for path in learned:
        mine[str(path)] = validation_record(load_policy(path, config), config, episodes, seeds)
        say(f"learned {path}: {mine[str(path)]}")
    floor = validation_record(make_policy(FLOOR_POLICY, config), config, episodes, seeds)
    folder.mkdir(parents=True, exist_ok=True)
    ceilings: dict[str, Any] = {}
    if hand:
        best = choose(hand)
        ceilings["handwritten"] = {
            "policy": best,
            "name": best,
            "file": None,
            "validation": hand[best],
        }
    if mine:
        best = choose(mine)
        export = torch.load(best, map_location="cpu", weights_only=True)
        shutil.copyfile(best, folder / "learned.pt")
        ceilings["learned"] = {
            "name": f"learned ({Path(best).parent.name})",
            "file": "learned.pt",
            "sha256": homes.sha256(folder / "learned.pt"),
            "source": _relative(Path(best)),
            "scenario": {
                "n_pursuers": export["scenario"]["n_pursuers"],
                "n_evaders": export["scenario"]["n_evaders"],
            },
            "validation": mine[best],
        }
    manifest = {
        "format": FORMAT,
        "commit": commit_id(),
        "rule": "the highest validation success less own crash rate (scale.choose)",
        "validation": {
            "episodes_per_seed": episodes,
            "seeds": list(seeds),
            "scenario": {"n_pursuers": config.n_pursuers, "n_evaders": config.n_evaders},
        },
        "floor": {"policy": FLOOR_POLICY, "validation": floor},
        "ceilings": ceilings,
        "candidates": {"handwritten": hand, "learned": mine},
    }
    (folder / homes.MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    say(f"wrote {folder / homes.MANIFEST} ({time.perf_counter() - start:.0f} s)")
    return folder


def _relative(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(homes.ROOT))
    except ValueError:
        return path.name
