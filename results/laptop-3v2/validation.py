"""The laptop experiment on the validation teammates: what each method's `best.pt` reached
there (the figure it was chosen by), whether its learners joined the population, and what
each trial cost. Reads the trials kept here (`trials/<method>-s<seed>/`: metrics.csv,
best.json, generations/gen_0000/metrics.json) or those of an experiment directory. A
trial's minutes are its generations plus its own pre-training; a trial that adopted
another trial's G_0 (the same seed's hola, hola_r, uniform and mep share one) counts none.

    python results/laptop-3v2/validation.py [EXPERIMENT_DIR] [--shipped]

--shipped, for an experiment whose trials adopt shipped populations (the comparison at
competence, configs/experiments/laptop.yaml, results/laptop-3v1/): it also says which
strategy each learner started from and which generation best.pt is, and counts only what
each trial trained in the experiment (the populations and the starts were built once,
before; their manifests say what they cost).
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


def summarize(trials: Path, shipped: bool = False) -> list[str]:
    methods: dict[str, list[Path]] = {}
    for folder in sorted(trials.iterdir()):
        if (folder / "best.json").is_file():
            methods.setdefault(folder.name.rsplit("-s", 1)[0], []).append(folder)
    lines = [
        "| method | seeds | best.pt val success | val collision | val own crash | "
        "learners accepted | env steps incl. pre-training (M) | learner samples (k) | minutes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    if shipped:
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
            for key in ("val_success", "val_collision", "val_learner_crash"):
                cols.setdefault(key, []).append(number(chosen, key))
            trained = [r for r in rows if int(r["generation"]) >= 1]
            pre = 0.0 if shipped else number(rows[0], "pretrain_env_steps")
            cols.setdefault("env", []).append(number(rows[-1], "env_steps") + pre)
            cols.setdefault("samples", []).append(number(rows[-1], "learner_samples"))
            zero = folder / "generations" / "gen_0000" / "metrics.json"
            adopted = zero.is_file() and "adopted_from" in json.loads(zero.read_text())
            own_pretrain = 0.0 if adopted else number(rows[0], "pretrain_s")
            counted = trained if shipped else rows
            cols.setdefault("minutes", []).append(
                (sum(number(r, "wall_s") for r in counted) + own_pretrain) / 60
            )
            if shipped:
                start = start_of(folder, rows)
                if method == "pbt":  # generation g trains agent (g − 1) mod K from its weights
                    start = start.split(" node ")[0] + " agents, in turn"
                starts.add(start)
                bests.append(str(best["generation"]))
            if any(r.get("accepted") for r in trained):
                joined = sum(r["accepted"] in ("1", "True", "true") for r in trained)
                accepted.append(f"{joined}/{len(trained)}")
        figures = (
            f"{mean_se(cols['val_success'])} | {mean_se(cols['val_collision'])} "
            f"| {mean_se(cols['val_learner_crash'])}"
        )
        if shipped:
            figures = f"{', '.join(sorted(starts))} | {figures} | {', '.join(bests)}"
        lines.append(
            f"| {method} | {len(folders)} | {figures} "
            f"| {', '.join(accepted) or '—'} "
            f"| {mean_se(cols['env'], 1e-6, 2)} | {mean_se(cols['samples'], 1e-3, 0)} "
            f"| {mean_se(cols['minutes'], 1.0)} |"
        )
    return lines


def main(argv: list[str]) -> int:
    shipped = "--shipped" in argv
    paths = [a for a in argv if a != "--shipped"]
    root = Path(paths[0]) if paths else HERE
    print("\n".join(summarize(root / "trials", shipped)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
