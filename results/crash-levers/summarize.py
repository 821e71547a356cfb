"""The lever table of results/NOTEBOOK.md ("Measured: why the learner crashes itself"), from
the runs kept here (each folder: config.yaml, metrics.csv, best.json, seated.json; NAME_s1,
NAME_s2 are seeds 1 and 2 of NAME):

    python results/crash-levers/summarize.py env samples samples_pre5 samples_pre5a0 \
        samples_col30 samples_shift1 own_move
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from hola_ray.evaluation.stats import mean_and_se

ROOT = Path(__file__).resolve().parent


def mean_se(xs: list[float]) -> str:
    """Mean ± s.e. over seeds, in percent; the mean alone for one seed."""
    m, se = mean_and_se(np.array(xs))
    return f"{100 * m:.1f}" if len(xs) < 2 else f"{100 * m:.1f} ± {100 * se:.1f}"


def row(variant: str, times: dict[str, int]) -> str:
    runs = [r for r in (variant, f"{variant}_s1", f"{variant}_s2") if (ROOT / r).is_dir()]
    cols: dict[str, list[float]] = {}

    def add(key: str, value: float) -> None:
        cols.setdefault(key, []).append(float(value))

    for r in runs:
        best = json.loads((ROOT / r / "best.json").read_text())
        rows = list(csv.DictReader((ROOT / r / "metrics.csv").open()))
        by_gen = {int(x["generation"]): x for x in rows}
        chosen = by_gen[best["generation"]]
        add("mem_success", by_gen[0]["members_success"])
        add("mem_crash", by_gen[0]["members_crash"])
        for k in ("val_success", "val_collision", "val_learner_crash"):
            add(k, chosen[k])
        add("last_success", sum(float(x["val_success"]) for x in rows[-3:]) / 3)
        add("last_crash", sum(float(x["val_learner_crash"]) for x in rows[-3:]) / 3)
        seated = json.loads((ROOT / r / "seated.json").read_text())
        learner = next(iter(seated.values()))["learner"]
        for k in ("success", "collision", "own"):
            add(f"seated_{k}", learner[k])
        add("minutes", times[r] / 60 / 100)  # mean_se prints × 100
    c = {k: mean_se(v) for k, v in cols.items()}
    return (
        f"| {variant} | {len(runs)} | {c['mem_success']} / {c['mem_crash']} "
        f"| {c['val_success']} | {c['val_collision']} | {c['val_learner_crash']} "
        f"| {c['last_success']} / {c['last_crash']} | {c['seated_success']} "
        f"| {c['seated_collision']} | {c['seated_own']} | {c['minutes']} |"
    )


def main(variants: list[str]) -> None:
    times = {}
    for line in (ROOT / "times.txt").read_text().splitlines():
        name, _, seconds = line.split()
        times[name] = int(seconds)
    for v in variants:
        print(row(v, times))


if __name__ == "__main__":
    main(sys.argv[1:])
