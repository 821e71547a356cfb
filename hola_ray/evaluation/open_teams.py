"""The open-team protocol (docs/contract.md §6.4; docs/open-teams.md): learners against unseen
teammate pools in every arena and team size, zero-shot and open, with the learner's scale.
The command: `python -m hola_ray evaluate --protocol open-teams`.

A cell is (arena, mode, team size n, pool). Its scenario is the learners' own (`base`: their
evaders, speeds, horizon) in the arena, with n seats observed in `SLOTS` pursuer slots, and
the default reward (`cell_scenario`):

- `zero-shot`: a fixed unseen team per episode, n pursuers from start to end;
- `open`: the team changes within the episode: it starts with n − 1 of the n seats flying
  (the learner's among them) and changes twice, at steps drawn in 5–25 % of the horizon: a
  teammate leaves (it lands) or the waiting seat joins, a coin deciding where both can
  (`open_team`).

In each cell every learner, and the reference seats, play the same episodes (the
evaluation's `hola_ray.evaluation.teams.play`: the learner in seat 0 where the team
changes, else a random seat; the other seats drawn from the pool per episode). A policy
trained for another team plays through `hola_ray.policies.adapter.ScenarioAdapter`. The
figures are AT-Drone's: success (SUC), collision (COL), steps to success (AST) and the
per-pursuer return (REW), with the learner's own crash, each with a 95 % interval from the
bootstrap of `hola_ray.evaluation.compare` over the cell's episodes (`unstratified`); the
learner's scale is the floor (a seat that holds its heading) and the ceilings on the same
episodes.

Differences A − B between learners are taken on the shared episodes, per cell and over
each mode's cells at once (`lead`: every cell's episodes resampled within that cell, each
cell weighing as its episodes do). With one trained seed per
learner an interval holds episode noise only: it says how these two learners differ on
these pools, not how two more seeds of their methods would.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.config.scenario import ARENAS, PursuitConfig, TeamChangeConfig
from hola_ray.evaluation.compare import compare, verdict
from hola_ray.evaluation.pools import load_pool
from hola_ray.evaluation.report import POOL_LABELS
from hola_ray.evaluation.scale import CEILINGS, FLOOR, load_references, play_references
from hola_ray.evaluation.teams import play
from hola_ray.policies.base import Policy

MODES = ("zero-shot", "open")
"""a fixed team per episode; a team that changes within it"""
SIZES = (2, 3, 4, 5)
"""the team sizes (seats) of contract §6.2"""
SLOTS = 5
"""the pursuer slots every cell's observation holds: the largest team"""
FIGURES = ("success", "collision", "steps_success", "reward", "learner_crash")
"""AT-Drone's SUC, COL, AST and REW, and the learner's own crash"""


WINDOW = (0.05, 0.25)
"""the share of the horizon the open mode's two changes fall in: competent teams end their
episodes in 300–500 steps, so changes drawn in 10–60 % (the default) were never met in half
of the episodes at 5 seats; in 5–25 % two are met in 64–91 % of them (Vicsek's copies, 128
episodes a cell, docs/open-teams.md)"""


def open_team(size: int) -> TeamChangeConfig:
    """The `open` mode's team at `size` seats (module doc)."""
    return TeamChangeConfig(present=size - 1, changes=2, min_team=1, fixed=1, window=WINDOW)


def cell_scenario(base: PursuitConfig, arena: str, mode: str, size: int) -> PursuitConfig:
    """The scenario of one cell: `base`'s evaders and physics, the default reward, in
    `arena`, with `size` seats observed in `SLOTS` slots (module doc)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if size not in SIZES:
        raise ValueError(f"team size must be one of {list(SIZES)}, got {size}")
    closed = dataclasses.replace(base, team=TeamChangeConfig(), arenas=())
    return dataclasses.replace(
        closed.in_arena(arena).played(),
        n_pursuers=size,
        obs_pursuers=SLOTS,
        obs_evaders=base.evader_slots,
        team=open_team(size) if mode == "open" else TeamChangeConfig(),
    )


def grid_base(scenarios: Sequence[PursuitConfig]) -> PursuitConfig:
    """The scenario the grid plays learners trained in `scenarios` in (`cell_scenario`'s
    `base`): the first, where they differ in the team and the arena only; ValueError where
    they differ beyond (evaders, speeds, horizon, sensing…), which one grid cannot hold."""
    cells = [cell_scenario(s, "paper", "zero-shot", 3) for s in scenarios]
    if any(cell != cells[0] for cell in cells):
        raise ValueError(
            "the learners were trained in scenarios that differ beyond the team and the "
            "arena (evaders, speeds, horizon, sensing…)"
        )
    return scenarios[0]


def _row(intervals: Mapping[str, Any]) -> dict[str, Any]:
    return {
        m: {"mean": intervals[m]["mean"], "ci95": list(intervals[m]["ci95"])}
        for m in FIGURES
        if m in intervals
    } | ({"normalised": intervals["normalised"]} if "normalised" in intervals else {})


def unstratified(played: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """`played` with every episode in one stratum. Partner combinations are too many to
    resample within at the larger teams (35 multisets of 4 of HeT's 4 members at 5 seats:
    about 6 of 200 episodes each, and a stratum of one episode never varies), so the
    protocol resamples episodes as a whole; every seat still draws the same episodes."""
    return dict(played) | {"stratum": np.zeros(len(played["success"]), dtype=np.int64)}


Groups = Mapping[str, Sequence[str]]
"""method → the names of its learners (its trained seeds, in the order of `training_seeds`)"""


def evaluate_cell(
    learners: Mapping[str, Policy],
    members: Sequence[Policy],
    references: Mapping[str, Policy],
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    groups: Groups,
    training_seeds: Mapping[str, Sequence[int]] | None = None,
) -> tuple[dict[str, Any], dict[str, dict[str, np.ndarray]]]:
    """One cell's figures (per method, its seeds and episodes resampled, and per reference
    seat), the methods' normalised scores and their differences (every pair, the paired
    seeds resampled together where `training_seeds` match), and every learner's and seat's
    episodes (for `lead`)."""
    played = {
        name: unstratified(play(p, list(members), config, episodes, seeds))
        for name, p in learners.items()
    }
    seats = {
        name: unstratified(v)
        for name, v in play_references(references, list(members), config, episodes, seeds).items()
    }
    ceilings = [c for c in CEILINGS if c in seats]
    scale = (FLOOR, ceilings) if FLOOR in seats and ceilings else None
    pairs = list(itertools.combinations(groups, 2))
    summary, diffs = compare(
        {
            **{m: [played[n] for n in names] for m, names in groups.items()},
            **{k: [v] for k, v in seats.items()},
        },
        pairs=pairs,
        seeds=training_seeds,
        scale=scale,
    )
    row: dict[str, Any] = {
        "learners": {m: _row(summary[m]) for m in groups},
        "references": {name: _row(summary[name]) for name in seats},
        "differences": {
            f"{a} − {b}": {m: _difference(diffs[f"{a}-{b}"][m], m) for m in FIGURES}
            for a, b in pairs
        },
        "episodes": episodes * len(seeds),
    }
    if any(len(names) > 1 for names in groups.values()):
        row["trials"] = {n: _row(compare({n: [played[n]]})[0][n]) for n in played}
    return row, played


def _difference(d: Mapping[str, Any], metric: str) -> dict[str, Any]:
    higher = metric in ("success", "reward")
    lower = metric in ("collision", "learner_crash", "steps_success")
    call = verdict(d, higher_is_better=higher) if higher or lower else "tie"
    return {"mean": d["mean"], "ci95": list(d["ci95"]), "verdict": call}


def lead(
    cells: Sequence[Mapping[str, Mapping[str, np.ndarray]]],
    pair: tuple[str, str],
    groups: Groups | None = None,
    training_seeds: Mapping[str, Sequence[int]] | None = None,
) -> dict[str, Any]:
    """A − B over several cells' episodes at once: each learner's episodes of every cell
    joined, every cell's resampled within that cell (its stratum made unique), a method's
    seeds resampled as in `compare`."""
    groups = groups or {name: [name] for name in pair}
    joined: dict[str, dict[str, list[np.ndarray]]] = {}
    for k, cell in enumerate(cells):
        for method in pair:
            for name in groups[method]:
                for field, values in cell[name].items():
                    if field == "stratum":
                        values = np.asarray(values, dtype=np.int64) * len(cells) + k
                    joined.setdefault(name, {}).setdefault(field, []).append(np.asarray(values))
    trials = {n: {f: np.concatenate(v) for f, v in fields.items()} for n, fields in joined.items()}
    stacked = {m: [trials[n] for n in groups[m]] for m in pair}
    summary, diffs = compare(stacked, pairs=[pair], seeds=training_seeds)
    a, b = pair
    key = f"{a}-{b}"
    first = groups[a][0]
    return {
        "cells": len(cells),
        "episodes": int(sum(len(c[first]["success"]) for c in cells)),
        a: _row(summary[a]),
        b: _row(summary[b]),
        "difference": {m: _difference(diffs[key][m], m) for m in FIGURES},
    }


class CellCache:
    """Every played cell kept in `folder` under the `settings` it was played with: its row
    (`<cell>.json`) and every seat's episodes (`<cell>.npz`, for the leads). A grid stopped
    part-way plays only the cells it had not kept; a cell kept under other settings is
    played again."""

    SEP = "|"

    def __init__(self, folder: Path, settings: Mapping[str, Any]):
        self.folder = Path(folder)
        self.settings = json.loads(json.dumps(dict(settings)))  # as a kept file reads back

    def _files(self, key: tuple[str, str, int, str]) -> tuple[Path, Path]:
        stem = "-".join(str(k) for k in key)
        return self.folder / f"{stem}.json", self.folder / f"{stem}.npz"

    def get(self, key: tuple[str, str, int, str]) -> tuple[dict, dict] | None:
        row_file, episodes_file = self._files(key)
        if not row_file.is_file():
            return None
        kept = json.loads(row_file.read_text())
        if kept.get("settings") != self.settings or not episodes_file.is_file():
            return None
        played: dict[str, dict[str, np.ndarray]] = {}
        with np.load(episodes_file, allow_pickle=False) as data:
            for k in data.files:
                name, field = k.split(self.SEP, 1)
                played.setdefault(name, {})[field] = data[k]
        return kept["row"], played

    def put(self, key: tuple[str, str, int, str], row: Mapping, played: Mapping) -> None:
        """The episodes first, the row (which `get` looks for) last, each whole or not at all."""
        self.folder.mkdir(parents=True, exist_ok=True)
        row_file, episodes_file = self._files(key)
        arrays = {
            f"{name}{self.SEP}{field}": np.asarray(values)
            for name, fields in played.items()
            for field, values in fields.items()
        }
        tmp = episodes_file.with_name(f".{episodes_file.name}")
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, episodes_file)
        tmp = row_file.with_name(f".{row_file.name}")
        tmp.write_text(json.dumps({"settings": self.settings, "row": row}, indent=1))
        os.replace(tmp, row_file)


def run_protocol(
    learners: Mapping[str, Callable[[PursuitConfig], Policy]],
    pools: Sequence[str],
    base: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    arenas: Sequence[str] = tuple(ARENAS),
    modes: Sequence[str] = MODES,
    sizes: Sequence[int] = SIZES,
    say: Callable[[str], None] = print,
    groups: Groups | None = None,
    training_seeds: Mapping[str, Sequence[int]] | None = None,
    cache: CellCache | None = None,
) -> dict[str, Any]:
    """Every cell of the protocol (module doc). `learners`: name → a function of a cell's
    scenario giving the learner as it plays it (`learner_loader`). `groups`: method → its
    learners (default: each learner a method of its own); `training_seeds`: each method's
    seeds, in the order of its learners (methods with the same ones resampled as pairs);
    `cache`: the cells already played under the same settings, taken as kept."""
    groups = {m: list(v) for m, v in (groups or {n: [n] for n in learners}).items()}
    pairs = list(itertools.combinations(groups, 2))
    cells: list[dict[str, Any]] = []
    per_mode: dict[tuple[str, str], list] = {}
    for key in itertools.product(arenas, modes, sizes, pools):
        arena, mode, size, pool = key
        start = time.perf_counter()
        kept = cache.get(key) if cache else None
        if kept is None:
            config = cell_scenario(base, arena, mode, size)
            members = list(load_pool(pool, config).values())
            references = load_references(config)
            seated = {name: make(config) for name, make in learners.items()}
            row, played = evaluate_cell(
                seated, members, references, config, episodes, seeds, groups, training_seeds
            )
            if cache:
                cache.put(key, row, played)
        else:
            row, played = kept
        cells.append({"arena": arena, "mode": mode, "size": size, "pool": pool} | row)
        per_mode.setdefault((mode, pool), []).append(played)
        figures = ", ".join(
            f"{m} {row['learners'][m]['success']['mean']:.1%}" for m in groups
        ) + "".join(
            f", {r} {row['references'][r]['success']['mean']:.1%}" for r in row["references"]
        )
        say(
            f"[{arena} {mode} {size} {POOL_LABELS.get(pool, pool)}] success {figures} "
            + ("(kept from an earlier run)" if kept else f"({time.perf_counter() - start:.0f} s)")
        )
    leads = {
        f"{mode}/{pool}": {
            f"{a} − {b}": lead(played, (a, b), groups, training_seeds) for a, b in pairs
        }
        for (mode, pool), played in per_mode.items()
    }
    return {
        "protocol": {
            "arenas": list(arenas),
            "modes": list(modes),
            "sizes": list(sizes),
            "pools": list(pools),
            "slots": SLOTS,
            "evaders": base.n_evaders,
            "episodes_per_seed": episodes,
            "seeds": [int(s) for s in seeds],
            "open_team": dataclasses.asdict(open_team(3)) | {"present": "size - 1"},
            "methods": groups,
            "training_seeds": {m: list(v) for m, v in (training_seeds or {}).items()},
        },
        "cells": cells,
        "leads": leads,
    }


def learner_loader(path: str | Path) -> Callable[[PursuitConfig], Policy]:
    """A learner file or run directory as a function of a cell's scenario: the policy built
    in the scenario it was trained in, fitted to the cell's (`load_fitted`)."""
    from hola_ray.policies.registry import load_fitted, played_scenario

    trained = played_scenario(path)  # read once; None for a D3QN-G export
    return lambda config: load_fitted(path, config, trained)


# ---- the report -----------------------------------------------------------------------------
def plot_arena(results: Mapping[str, Any], arena: str, path: Path) -> Path:
    """One arena's figure: success by team size, zero-shot (top) and open (bottom), one
    column per pool; each learner with its 95 % interval, the floor and the hand-written
    ceiling dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    protocol = results["protocol"]
    pools, modes, sizes = protocol["pools"], protocol["modes"], protocol["sizes"]
    cells = [c for c in results["cells"] if c["arena"] == arena]
    fig, axes = plt.subplots(
        len(modes), len(pools), figsize=(4.2 * len(pools), 3.2 * len(modes)), squeeze=False
    )
    names = list(cells[0]["learners"]) if cells else []
    colours = plt.cm.tab10(np.arange(len(names)) % 10)
    for (i, mode), (j, pool) in itertools.product(enumerate(modes), enumerate(pools)):
        ax = axes[i, j]
        here = {c["size"]: c for c in cells if c["mode"] == mode and c["pool"] == pool}
        xs = [n for n in sizes if n in here]
        for k, name in enumerate(names):
            mean = np.array([here[n]["learners"][name]["success"]["mean"] for n in xs])
            lo, hi = (
                np.array([here[n]["learners"][name]["success"]["ci95"][e] for n in xs])
                for e in (0, 1)
            )
            shift = (k - (len(names) - 1) / 2) * 0.06
            ax.errorbar(
                np.array(xs) + shift,
                mean,
                yerr=[mean - lo, hi - mean],
                marker="o",
                capsize=3,
                color=colours[k],
                label=name,
            )
        for ref, style in ((FLOOR, "--"), (CEILINGS[0], ":")):
            values = [here[n]["references"].get(ref, {}).get("success", {}).get("mean") for n in xs]
            if any(v is not None for v in values):
                ax.plot(xs, values, style, color="0.4", lw=1, label=f"{ref} (reference seat)")
        ax.set_title(f"{mode}, {POOL_LABELS.get(pool, pool)}", fontsize=10)
        ax.set_xticks(list(sizes))
        ax.set_ylim(0, 1)
        ax.set_xlabel("pursuers (seats)")
        ax.set_ylabel("success")
        ax.grid(alpha=0.3)
    if names:
        axes[0, 0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"arena {arena}: success by team size (95 % intervals)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def table(results: Mapping[str, Any]) -> list[str]:
    """Markdown: every cell's SUC, COL, AST, REW and own crash per learner (95 % intervals),
    the reference seats' success, then the leads per mode and pool."""

    def cell(f: Mapping[str, Any], m: str) -> str:
        mean, (lo, hi) = f["mean"], f["ci95"]
        if m in ("steps_success", "reward"):
            return f"{mean:.1f} [{lo:.1f}, {hi:.1f}]"
        return f"{mean:.1%} [{lo:.1%}, {hi:.1%}]"

    lines = [
        "SUC success, COL collision, AST steps to success, REW return per pursuer, own crash "
        "the learner's seat's; 95 % intervals over the cell's episodes. The scale: the "
        "reference seats' success on the same episodes (the floor holds its heading; the "
        "ceilings are the hand-written pursuer and, where one plays the size, a learned one).",
        "",
        "| arena | mode | n | pool | learner | SUC | COL | AST | REW | own crash | scale (SUC) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for c in results["cells"]:
        refs = ", ".join(f"{ref} {f['success']['mean']:.1%}" for ref, f in c["references"].items())
        for name, f in c["learners"].items():
            cells = " | ".join(cell(f[m], m) for m in FIGURES)
            lines.append(
                f"| {c['arena']} | {c['mode']} | {c['size']} | "
                f"{POOL_LABELS.get(c['pool'], c['pool'])} | {name} | {cells} | {refs} |"
            )
    lines += ["", "| mode / pool | A − B | cells | ΔSUC | ΔCOL | ΔREW | verdict (SUC) |"]
    lines.append("| --- | --- | --- | --- | --- | --- | --- |")
    for key, by_pair in results["leads"].items():
        for pair, d in by_pair.items():
            diff = d["difference"]
            lines.append(
                f"| {key} | {pair} | {d['cells']} | "
                + " | ".join(
                    f"{diff[m]['mean']:+.3f} [{diff[m]['ci95'][0]:+.3f}, {diff[m]['ci95'][1]:+.3f}]"
                    for m in ("success", "collision", "reward")
                )
                + f" | {diff['success']['verdict']} |"
            )
    return lines


def report(results: Mapping[str, Any], out: Path) -> list[Path]:
    """results.json's figures as one PNG per arena and results.md; returns the files."""
    out.mkdir(parents=True, exist_ok=True)
    written = [
        plot_arena(results, arena, out / f"open-teams-{arena}.png")
        for arena in results["protocol"]["arenas"]
    ]
    md = out / "results.md"
    md.write_text("\n".join(table(results)) + "\n")
    return [*written, md]
