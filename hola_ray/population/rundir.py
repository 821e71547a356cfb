"""The run directory: everything a run leaves on disk, written so a kill loses nothing.

    RUN_DIR/
      config.yaml                 the validated run config
      members/node_0007.pt        every member's plain-torch export (`MLPPolicy.load`)
      members/node_0007.rllib.pt  its full RLlib module state (to seat it as a partner again)
      generations/gen_0003/       one folder per completed generation (0 = pre-training):
        state.json                population, slots, next node id, the decision
        hyfog.json  phi.json      the HyFoG and φ after the generation
        metrics.json              the generation's metrics
        monitors.json             its figures that decide nothing during training
                                  (validation, the population as a team), played while
                                  the next generation trained and written after the
                                  folder; metrics.csv joins the two
        learner.rllib.pt          the learner's RLlib state at the end of the generation
        learner.pt                its plain-torch export (the folder plays on its own)
        learner.training.pt       its Adam state, KL coefficient and env steps so far
                                  (what `--resume` trains on with)
        iterations.json           one row per PPO iteration (spread, entropy, KL, return)
      metrics.csv                 one row per completed generation
      iterations.csv              one row per PPO iteration of every completed generation
      tb/                         TensorBoard events of the same metrics
      learner.pt, learner.json    the final learner: the Oracle's learner after the last
                                  generation, plain torch, whether or not the coordinator
                                  accepted it (learner.json: its generation, whether it
                                  joined the population and as which node)
      best.pt, best.json          the learner of the generation judged best (success, then
                                  lower collision) and what it was judged on
      population/                 the accepted population after the last generation:
                                  slot_K.pt per member, members.json (slot → node, η, φ)

The coordinator writes and reads the torch files as bytes (`TorchFile`): torch is loaded
where they are made and opened, in the driver, never in the coordinator's process.

A generation folder is written under a temporary name and renamed into place, so it is
either complete or absent: the last complete folder is where `--resume` starts. The files
at the top (learner.pt, learner.json, best.pt, best.json) are written after it; a run killed
in between gets them again from the generation folders when it is resumed
(`Trainer.fit`, `learner_generation` says which generation learner.pt holds).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.homes import GENERATION_EXPORT, GENERATION_STATE
from hola_ray.population.files import (
    Saved,
    atomic_torch_save,
    atomic_write_text,
    fsync_dir,
    load_state,
    torch_save,
    write_csv,
)

GENERATION_TRAINING = "learner.training.pt"
"""in a generation folder: the learner's optimizer state and schedule position"""

GEN_PREFIX = "gen_"

MONITORS = "monitors.json"
"""in a generation folder: the generation's monitored figures (`RunDir.complete`)"""


def best_score(row: Mapping[str, Any]) -> tuple[float, float]:
    """What `best.pt` is judged on, the one rule for every method: success with the
    validation teammates, then lower collision there; a run without validation teammates
    falls back on its own judging (learner success, then lower learner collision)."""
    if row.get("val_success") not in (None, ""):
        return float(row["val_success"]), -float(row["val_collision"])
    return float(row["learner_success"]), -float(row["learner_collision"])


PHI_TIE = 0.01
"""φ within this total variation of the rival rule's in every generation: one draw"""


def phi_departure(rows: Sequence[Mapping[str, Any]]) -> float | None:
    """The largest distance (`phi_tv`) between the φ a run trained with and its rival
    rule's over its generations, or None for a run without a rival (`Method.rival`)."""
    tv = [float(r["phi_tv"]) for r in rows if r.get("phi_tv") not in (None, "")]
    return max(tv) if tv else None


def phi_tie(rows: Sequence[Mapping[str, Any]], rival: str) -> str | None:
    """What a run says when its φ never departed from its rival rule's (`rival`: its name)
    by more than `PHI_TIE`; None when it did, or had no rival."""
    departed = phi_departure(rows)
    if departed is None or departed > PHI_TIE:
        return None
    return (
        f"φ never departed from {rival}'s by more than {PHI_TIE} (at most {departed:.4f}, "
        "total variation): this run drew its partners as that rule does"
    )


class RunDir:
    """Paths and atomic reads/writes of one run's directory."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.members = self.root / "members"
        self.generations = self.root / "generations"
        self.config = self.root / "config.yaml"
        self.metrics_csv = self.root / "metrics.csv"
        self.iterations_csv = self.root / "iterations.csv"
        self.tensorboard = self.root / "tb"
        self.learner = self.root / "learner.pt"
        self.best = self.root / "best.pt"
        self.best_info = self.root / "best.json"
        self.population = self.root / "population"
        self.pretrain = self.root / "pretrain"

    def create(self, config_yaml: str) -> None:
        self.members.mkdir(parents=True, exist_ok=True)
        self.generations.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.config, config_yaml)

    # ---- members ------------------------------------------------------------------------
    def member_export(self, node: int) -> Path:
        return self.members / f"node_{node:04d}.pt"

    def member_state(self, node: int) -> Path:
        return self.members / f"node_{node:04d}.rllib.pt"

    def save_member(self, node: int, export: Saved, state: Saved) -> None:
        atomic_torch_save(export, self.member_export(node))
        atomic_torch_save(state, self.member_state(node))

    def load_member_state(self, node: int) -> dict[str, Any]:
        return load_state(self.member_state(node))

    def load_member_export(self, node: int) -> dict[str, Any]:
        return load_state(self.member_export(node))

    def write_population(self, members: Mapping[int, Mapping[str, Any]], generation: int) -> None:
        """`population/`: the accepted population after `generation`, apart from the final
        learner: `slot_K.pt` per member (a copy of its node's export) and `members.json`
        (slot → node, η, φ). Rewritten whole at every generation."""
        tmp = self.root / "population.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        table = {}
        for node, info in sorted(members.items(), key=lambda kv: kv[1]["slot"]):
            name = f"slot_{info['slot']}.pt"
            shutil.copyfile(self.member_export(node), tmp / name)
            table[str(info["slot"])] = {"node": node, "file": name, **dict(info)}
        (tmp / "members.json").write_text(
            json.dumps({"generation": generation, "members": table}, indent=1)
        )
        old = self.root / "population.old"
        shutil.rmtree(old, ignore_errors=True)
        if self.population.exists():
            os.replace(self.population, old)
        os.replace(tmp, self.population)
        shutil.rmtree(old, ignore_errors=True)

    def save_learner_info(self, info: Mapping[str, Any]) -> None:
        atomic_write_text(self.root / "learner.json", json.dumps(dict(info), indent=1))

    def finished(self, generations: int) -> bool:
        """Every generation up to `generations` is complete, and so are the files at the
        top (learner.json, written last, is of the last one)."""
        last = self.last_completed()
        return (
            last is not None
            and last >= generations
            and self.learner_generation() == last
            and self.monitored(last)
        )

    def learner_generation(self) -> int | None:
        """The generation whose learner `learner.pt` holds (learner.json), if any."""
        info = self.root / "learner.json"
        if not info.is_file() or not self.learner.is_file():
            return None
        return int(json.loads(info.read_text())["generation"])

    def save_learner(self, export: Mapping[str, Any]) -> None:
        """The latest learner as a plain-torch export (`MLPPolicy.load(config, path)`)."""
        atomic_torch_save(export, self.learner)

    def save_latest(
        self, g: int, method: str, export: Mapping[str, Any], decision: Mapping | None
    ) -> None:
        """learner.pt and learner.json (written last: it says generation g's files at the
        top are whole): generation g's learner and whether it joined the population."""
        accepted = decision is not None and bool(decision["accepted"])
        self.save_learner(export)
        self.save_learner_info(
            {
                "generation": g,
                "method": method,
                "in_population": None if decision is None else accepted,
                "node": decision["candidate"] if accepted else None,
                "population": "population/members.json" if decision is not None else None,
            }
        )

    def best_generation(self) -> int | None:
        """The generation whose learner `best.pt` holds, if any."""
        if not self.best_info.is_file():
            return None
        return int(json.loads(self.best_info.read_text())["generation"])

    def keep_best(self, g: int, row: Mapping[str, Any], export: Mapping[str, Any]) -> bool:
        """Make generation g's learner `best.pt` if it judged better than the one kept:
        higher learner_success, then lower learner_collision. Returns whether it did."""
        if self.best_info.is_file():
            kept = json.loads(self.best_info.read_text())
            if best_score(row) <= best_score(kept):
                return False
        validated = row.get("val_success") not in (None, "")
        info = {
            "generation": g,
            "learner_success": float(row["learner_success"]),
            "learner_collision": float(row["learner_collision"]),
            "learner_length": float(row["learner_length"]),
            "env_steps": int(row.get("env_steps", 0)),
            "judged_by": (
                "highest val_success, then lowest val_collision: the learner with the "
                "validation teammates"
                if validated
                else "highest learner_success, then lowest learner_collision, over the "
                "generations' own judging (self-play rollout, or the Grapher's hyperedges)"
            ),
        }
        if validated:
            info |= {k: float(row[k]) for k in ("val_success", "val_collision")}
        if export.get("commit"):
            info["commit"] = export["commit"]  # the commit that trained it, as best.pt says
        atomic_torch_save(export, self.best)
        atomic_write_text(self.best_info, json.dumps(info, indent=1))
        return True

    def best_of_completed(self) -> int | None:
        """The completed generation `keep_best` picks, generation by generation, from
        their metrics (the earliest of equal scores); None before generation 1."""
        best, kept = None, None
        for g in self.completed():
            if g < 1 or not self.learner_state(g).is_file():
                continue
            score = best_score(self.metrics(g))
            if kept is None or score > kept:
                best, kept = g, score
        return best

    # ---- generations --------------------------------------------------------------------
    def generation(self, g: int) -> Path:
        return self.generations / f"{GEN_PREFIX}{g:04d}"

    def learner_state(self, g: int) -> Path:
        """Generation g's learner, its RLlib state (absent for pre-training)."""
        return self.generation(g) / GENERATION_STATE

    def completed(self) -> list[int]:
        """Completed generations in order (leftover temporary folders are ignored)."""
        if not self.generations.is_dir():
            return []
        out = []
        for p in self.generations.iterdir():
            name = p.name
            if p.is_dir() and name.startswith(GEN_PREFIX) and name[len(GEN_PREFIX) :].isdigit():
                out.append(int(name[len(GEN_PREFIX) :]))
        return sorted(out)

    def last_completed(self) -> int | None:
        done = self.completed()
        return done[-1] if done else None

    def write_generation(
        self,
        g: int,
        files: Mapping[str, Any],
        learner_state: Saved | None,
        learner_export: Saved | None = None,
        learner_training: Saved | None = None,
    ) -> Path:
        """Write generation g's folder atomically: JSON files from `files`, the learner's
        RLlib state, its plain-torch export (which `load_policy` plays) and its training
        state (Adam's moments, what `--resume` trains on with)."""
        final = self.generation(g)
        if final.exists():
            raise FileExistsError(f"generation {g} is already complete in {final}")
        tmp = self.generations / f".tmp_{GEN_PREFIX}{g:04d}_{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        for name, payload in files.items():
            (tmp / name).write_text(json.dumps(payload, indent=1))
        for saved, name in (
            (learner_state, GENERATION_STATE),
            (learner_export, GENERATION_EXPORT),
            (learner_training, GENERATION_TRAINING),
        ):
            if saved is not None:
                torch_save(saved, tmp / name)
        fsync_dir(tmp)
        os.rename(tmp, final)
        fsync_dir(self.generations)
        return final

    def adopt_generation_zero(self, donor: RunDir) -> None:
        """Make `donor`'s generation 0 (its pre-trained members and G_0) this run's own:
        the members' files, then the generation folder (renamed into place, so it arrives
        whole). How partners are drawn and who joins are the method's, not the folder's."""
        state = donor.read_json(0, "state.json")
        nodes = [int(v) for v in state["population"]["slots"]]
        self.members.mkdir(parents=True, exist_ok=True)
        for v in nodes:
            for source in (donor.member_export(v), donor.member_state(v)):
                shutil.copyfile(source, self.members / source.name)
        tmp = self.generations / f".tmp_{GEN_PREFIX}0000_{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.copytree(donor.generation(0), tmp)
        metrics = json.loads((tmp / "metrics.json").read_text())
        metrics["adopted_from"] = donor.root.name
        (tmp / "metrics.json").write_text(json.dumps(metrics, indent=1))
        fsync_dir(tmp)
        os.rename(tmp, self.generation(0))
        fsync_dir(self.generations)
        self.rewrite_metrics_csv()

    def read_json(self, g: int, name: str) -> Any:
        return json.loads((self.generation(g) / name).read_text())

    def metrics(self, g: int) -> dict[str, Any]:
        """Generation g's metrics row: metrics.json and, once written, monitors.json."""
        row = self.read_json(g, "metrics.json")
        if (self.generation(g) / MONITORS).is_file():
            row |= self.read_json(g, MONITORS)
        return row

    def monitored(self, g: int) -> bool:
        """Whether generation g's monitored figures are written (`complete`), or were never
        to come apart (a row that does not say `monitored: 0`, written before monitors were
        played while the next generation trained)."""
        if (self.generation(g) / MONITORS).is_file():
            return True
        return self.read_json(g, "metrics.json").get("monitored", 1) != 0

    def complete(self, g: int, figures: Mapping[str, Any]) -> None:
        """Write generation g's monitored figures beside its metrics (atomically: the
        generation is monitored or not), then metrics.csv again."""
        atomic_write_text(self.generation(g) / MONITORS, json.dumps(dict(figures), indent=1))
        self.rewrite_metrics_csv()

    def load_learner_state(self, g: int) -> dict[str, Any] | None:
        path = self.learner_state(g)
        if not path.exists():
            return None
        return load_state(path)

    def load_learner_export(self, g: int) -> dict[str, Any] | None:
        """Generation g's learner as its plain-torch export (None for pre-training)."""
        path = self.generation(g) / GENERATION_EXPORT
        return load_state(path) if path.exists() else None

    def load_training_state(self, g: int) -> dict[str, Any] | None:
        """Generation g's learner training state (`Oracle.training_state`); None in a folder
        written before generations kept it (a resume then starts a fresh optimizer)."""
        path = self.generation(g) / GENERATION_TRAINING
        return load_state(path) if path.exists() else None

    # ---- pre-training checkpoints ---------------------------------------------------------
    def save_pretrain(self, states: Mapping[str, Mapping[str, Any]], progress: Mapping) -> None:
        """`pretrain/`: the pre-training members' RLlib states after a check (plain .npz
        arrays, nothing pickled) and `progress.json` (env steps done, the checks so far),
        written last: a build stopped mid-way resumes from its last check."""
        self.pretrain.mkdir(parents=True, exist_ok=True)
        for mid, state in states.items():
            tmp = self.pretrain / f".tmp_{mid}.npz"
            np.savez(tmp, **{k: np.asarray(v) for k, v in state.items()})
            os.replace(tmp, self.pretrain / f"{mid}.npz")
        atomic_write_text(self.pretrain / "progress.json", json.dumps(dict(progress), indent=1))

    def load_pretrain(self) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, Any]] | None:
        """The last pre-training checkpoint (`save_pretrain`), or None."""
        path = self.pretrain / "progress.json"
        if not path.is_file():
            return None
        progress = json.loads(path.read_text())
        states = {}
        for mid in progress["members"]:
            with np.load(self.pretrain / f"{mid}.npz", allow_pickle=False) as data:
                states[mid] = {k: data[k] for k in data.files}
        return states, progress

    def clean_partial(self) -> None:
        """Remove half-written generation folders left by a killed driver."""
        if self.generations.is_dir():
            for p in self.generations.glob(f".tmp_{GEN_PREFIX}*"):
                shutil.rmtree(p, ignore_errors=True)

    # ---- metrics ------------------------------------------------------------------------
    def metrics_rows(self) -> list[dict[str, Any]]:
        """Every completed generation's metrics, with `cumulative_wall_s`: the run's wall
        time up to the end of that generation (`generation_wall_s` summed; the time a stopped
        run waited before `--resume` is not in it)."""
        rows, total = [], 0.0
        for g in self.completed():
            row = self.metrics(g)
            total += generation_wall_s(row)
            rows.append({**row, "cumulative_wall_s": round(total, 2)})
        return rows

    def iteration_rows(self) -> list[dict[str, Any]]:
        """Every completed generation's PPO iterations, each row tagged with its generation."""
        rows = []
        for g in self.completed():
            path = self.generation(g) / "iterations.json"
            if path.is_file():
                rows += [{"generation": g, **r} for r in json.loads(path.read_text())]
        return rows

    def rewrite_metrics_csv(self) -> None:
        """metrics.csv and iterations.csv from the completed generations' folders (never a
        lost or doubled row, whatever was killed when)."""
        write_csv(self.metrics_csv, self.metrics_rows())
        write_csv(self.iterations_csv, self.iteration_rows())


def generation_wall_s(row: dict[str, Any]) -> float:
    """A generation's wall time from its metrics: `wall_s`, or for rows written before
    every generation had one, its phases' times. A generation 0 adopted from another run
    counts the time it took there: the population is part of the method's cost."""
    if row.get("wall_s") not in (None, ""):
        return float(row["wall_s"])
    phases = ("pretrain_s", "oracle_s", "grapher_s", "eval_s", "coordinator_s")
    return sum(float(row.get(k) or 0.0) for k in phases)


def metrics_differences(a: str | Path, b: str | Path) -> dict[int, dict[str, tuple]]:
    """Where two runs' metrics.csv differ, wall times aside (fields ending in `_s` or
    `_per_s`): {generation: {field: (a's, b's)}}; empty when they agree. The same config
    and seed on one machine give none (`python -m hola_ray.run` fixes the hash seed)."""
    rows = [RunDir(x).metrics_rows() for x in (a, b)]
    if len(rows[0]) != len(rows[1]):
        return {-1: {"generations": (len(rows[0]), len(rows[1]))}}
    out: dict[int, dict[str, tuple]] = {}
    for x, y in zip(*rows, strict=True):
        diff = {
            k: (x[k], y.get(k))
            for k in x
            if not k.endswith(("_s", "_per_s")) and not _same(x[k], y.get(k))
        }
        if diff:
            out[int(x["generation"])] = diff
    return out


def _same(x: Any, y: Any) -> bool:
    return x == y or (isinstance(x, float) and isinstance(y, float) and x != x and y != y)
