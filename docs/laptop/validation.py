"""The laptop experiment on the validation teammates: what each method's `best.pt` reached
there (the figure it was chosen by), whether its learners joined the population, and what
each trial cost. Reads the trials kept here (`trials/<method>-s<seed>/`: metrics.csv,
best.json, generations/gen_0000/metrics.json) or those of an experiment directory. A
trial's minutes are its generations plus its own pre-training; a trial that adopted
another trial's G_0 (the same seed's hola, hola_r, uniform and mep share one) counts none.

    python docs/laptop/validation.py [EXPERIMENT_DIR]
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

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


def summarize(trials: Path) -> list[str]:
    methods: dict[str, list[Path]] = {}
    for folder in sorted(trials.iterdir()):
        if (folder / "best.json").is_file():
            methods.setdefault(folder.name.rsplit("-s", 1)[0], []).append(folder)
    lines = [
        "| method | seeds | best.pt val success | val collision | val own crash | "
        "learners accepted | env steps incl. pre-training (M) | learner samples (k) | minutes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for method, folders in methods.items():
        cols: dict[str, list[float]] = {}
        accepted = []
        for folder in folders:
            best = json.loads((folder / "best.json").read_text())
            rows = list(csv.DictReader((folder / "metrics.csv").open()))
            chosen = next(r for r in rows if int(r["generation"]) == best["generation"])
            for key in ("val_success", "val_collision", "val_learner_crash"):
                cols.setdefault(key, []).append(number(chosen, key))
            pre = number(rows[0], "pretrain_env_steps")
            cols.setdefault("env", []).append(number(rows[-1], "env_steps") + pre)
            cols.setdefault("samples", []).append(number(rows[-1], "learner_samples"))
            zero = folder / "generations" / "gen_0000" / "metrics.json"
            adopted = zero.is_file() and "adopted_from" in json.loads(zero.read_text())
            own_pretrain = 0.0 if adopted else number(rows[0], "pretrain_s")
            cols.setdefault("minutes", []).append(
                (sum(number(r, "wall_s") for r in rows) + own_pretrain) / 60
            )
            trained = [r for r in rows if int(r["generation"]) >= 1]
            if any(r.get("accepted") for r in trained):
                joined = sum(r["accepted"] in ("1", "True", "true") for r in trained)
                accepted.append(f"{joined}/{len(trained)}")
        lines.append(
            f"| {method} | {len(folders)} | {mean_se(cols['val_success'])} "
            f"| {mean_se(cols['val_collision'])} | {mean_se(cols['val_learner_crash'])} "
            f"| {', '.join(accepted) or '—'} "
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
