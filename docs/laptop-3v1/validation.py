"""The comparison at competence (configs/experiments/laptop.yaml) on the validation
teammates: what each method's `best.pt` reached there (the figure it was chosen by), which
strategy its learner started from, whether its learners joined the population, and what
each trial trained and cost in this experiment. The shipped population a trial adopted
(and the training its learner's start inherited) was built once, before, and is not in
its env steps or minutes: see the population's manifest.

    python docs/laptop-3v1/validation.py [EXPERIMENT_DIR]
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import yaml

from hola_ray.evaluation.stats import mean_and_se

HERE = Path(__file__).resolve().parent


def mean_se(xs: list[float], scale: float = 100.0, digits: int = 1) -> str:
    """Mean ± s.e. over seeds (× scale); the mean alone for one seed."""
    m, se = mean_and_se(np.array(xs, dtype=float))
    if len(xs) < 2:
        return f"{scale * m:.{digits}f}"
    return f"{scale * m:.{digits}f} ± {scale * se:.{digits}f}"


def number(row: dict[str, str], key: str) -> float:
    value = row.get(key) or ""
    return float(value) if value else 0.0


def start_of(folder: Path, rows: list[dict[str, str]]) -> str:
    """Where the learner started: a shipped population's node, or random weights."""
    zero = folder / "generations" / "gen_0000" / "metrics.json"
    if zero.is_file():  # a population method: the population it adopted
        population = json.loads(zero.read_text()).get("adopted_from", "its own G_0")
    else:  # self-play: the population its start was taken from
        config = yaml.safe_load((folder / "config.yaml").read_text())
        population = config.get("pretrain", {}).get("population", "none")
    first = next((r for r in rows if int(r["generation"]) == 1), {})
    node = first.get("learner_start_node") or ""
    return f"{population} node {int(float(node))}" if node else "random"


def summarize(trials: Path) -> list[str]:
    methods: dict[str, list[Path]] = {}
    for folder in sorted(trials.iterdir()):
        if (folder / "best.json").is_file():
            methods.setdefault(folder.name.rsplit("-s", 1)[0], []).append(folder)
    lines = [
        "| method | seeds | learner starts from | best.pt val success | val collision "
        "| val own crash | best generation | learners accepted | env steps (M) "
        "| learner samples (k) | minutes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for method, folders in methods.items():
        cols: dict[str, list[float]] = {}
        accepted, starts, bests = [], set(), []
        for folder in folders:
            best = json.loads((folder / "best.json").read_text())
            rows = list(csv.DictReader((folder / "metrics.csv").open()))
            chosen = next(r for r in rows if int(r["generation"]) == best["generation"])
            bests.append(str(best["generation"]))
            for key in ("val_success", "val_collision", "val_learner_crash"):
                cols.setdefault(key, []).append(number(chosen, key))
            trained = [r for r in rows if int(r["generation"]) >= 1]
            cols.setdefault("env", []).append(number(rows[-1], "env_steps"))
            cols.setdefault("samples", []).append(number(rows[-1], "learner_samples"))
            cols.setdefault("minutes", []).append(sum(number(r, "wall_s") for r in trained) / 60)
            starts.add(start_of(folder, rows))
            if any(r.get("accepted") for r in trained):
                joined = sum(r["accepted"] in ("1", "True", "true") for r in trained)
                accepted.append(f"{joined}/{len(trained)}")
        lines.append(
            f"| {method} | {len(folders)} | {', '.join(sorted(starts))} "
            f"| {mean_se(cols['val_success'])} "
            f"| {mean_se(cols['val_collision'])} | {mean_se(cols['val_learner_crash'])} "
            f"| {', '.join(bests)} | {', '.join(accepted) or '—'} "
            f"| {mean_se(cols['env'], 1e-6, 2)} | {mean_se(cols['samples'], 1e-3, 0)} "
            f"| {mean_se(cols['minutes'], 1.0)} |"
        )
    return lines


def main(argv: list[str]) -> int:
    root = Path(argv[0]) if argv else HERE
    print("\n".join(summarize(root / "trials")))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
