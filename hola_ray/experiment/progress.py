"""Where an experiment stands, from its directory alone (`python -m hola_ray status DIR`):
every trial's state, seed by method, and the training left at the pace its trials kept.

Read from the trials' folders (what is on disk, whether or not the experiment runs) and
`DIR/progress.json` (which trials the driver last said were running or had failed). Nothing
of the evaluation is read: an experiment under way shows no result.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path
from typing import Any

from hola_ray.experiment.config import CONFIG_NAME, Experiment, trial_name
from hola_ray.experiment.runner import Runner


def standing(out: Path) -> dict[str, Any]:
    """Per trial its state ('done', 'running', 'failed', 'partial' or 'new'), last complete
    generation and generations; the seconds a generation took (the mean over the trained
    generations on disk, wall time) and the generations left."""
    out = Path(out)
    experiment = Experiment.from_yaml(out / CONFIG_NAME)
    runner = Runner(experiment, out)
    said_path = out / "progress.json"
    said = json.loads(said_path.read_text()) if said_path.is_file() else {}
    trials: dict[str, dict[str, Any]] = {}
    walls: list[float] = []
    for t, (state, last) in runner.states().items():
        if state != "done" and said.get(t, {}).get("status") in ("running", "failed"):
            state = said[t]["status"]
        generations = runner.configs[t].generations
        trials[t] = {"state": state, "generation": last, "generations": generations}
        walls += _generation_walls(runner.trial_dir(t) / "metrics.csv")
    left = sum(
        0 if r["state"] == "done" else r["generations"] - (r["generation"] or 0)
        for r in trials.values()
    )
    return {
        "dir": str(out),
        "methods": list(experiment.methods),
        "seeds": list(experiment.seeds),
        "trials": trials,
        "generations_left": left,
        "s_per_generation": sum(walls) / len(walls) if walls else None,
        "generations_timed": len(walls),
        "progress_age_s": time.time() - said_path.stat().st_mtime if said else None,
    }


def _generation_walls(metrics: Path) -> list[float]:
    """The wall times of a trial's learner generations (1 on; generation 0 builds or
    adopts its population) from its metrics.csv."""
    if not metrics.is_file():
        return []
    with metrics.open() as f:
        return [
            float(r["wall_s"])
            for r in csv.DictReader(f)
            if r.get("wall_s") not in (None, "") and int(float(r["generation"])) >= 1
        ]


def format_standing(view: dict[str, Any]) -> str:
    """The view as a table of seeds by methods (`done`, `g/N`, `new`), a count per state
    and the time left at the pace kept."""
    trials = view["trials"]
    counts: dict[str, int] = {}
    for r in trials.values():
        counts[r["state"]] = counts.get(r["state"], 0) + 1
    names = {"new": "not started", "partial": "stopped part way"}
    lines = [
        f"experiment {view['dir']}: {len(view['methods'])} method(s) × {len(view['seeds'])} "
        f"seed(s) = {len(trials)} trials; "
        + ", ".join(
            f"{n} {names.get(s, s)}" for s, n in sorted(counts.items(), key=lambda kv: -kv[1])
        )
    ]
    width = max(6, *(len(m) for m in view["methods"]))
    lines.append("  seed  " + " ".join(f"{m:>{width}}" for m in view["methods"]))
    for seed in view["seeds"]:
        cells = []
        for m in view["methods"]:
            r = trials[trial_name(m, seed)]
            if r["state"] == "done":
                cell = "done"
            elif r["state"] == "new":
                cell = "-"
            else:
                mark = {"running": "", "failed": " FAILED", "partial": " (stopped)"}[r["state"]]
                cell = f"{r['generation'] or 0}/{r['generations']}{mark}"
            cells.append(f"{cell:>{width}}")
        lines.append(f"  {seed:>4}  " + " ".join(cells))
    pace = view["s_per_generation"]
    if pace is not None and view["generations_left"]:
        hours = view["generations_left"] * pace / 3600
        lines.append(
            f"  {view['generations_left']} generations left: about {hours:.1f} h of training "
            f"one trial at a time, at the {pace:.0f} s a generation took here "
            f"(mean of {view['generations_timed']})"
        )
    if view["progress_age_s"] is not None:
        lines.append(f"  the driver's progress.json is {view['progress_age_s'] / 60:.0f} min old")
    return "\n".join(lines)
