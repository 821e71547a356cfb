"""How far learners move, how much seeds differ, and how many seeds a comparison needs.

    python benchmarks/movement.py EXPERIMENT_DIR [--a hola --b uniform] [--half-width 0.06]
        [--key val_success] [--with-start] [--out DIR]

Reads every trial of an experiment directory (`trials/<method>-s<seed>/metrics.csv`) and,
on the validation teammates only (never an evaluation pool: a pilot sizes a design):
- each learner's curve, `--key` against generation (generations ≥ 1), and its least-squares
  slope in points a generation with the slope's standard error; with `--with-start`, the
  common start (`pretrain.start_agent` of each trial's config) played with the same
  validation teammates and episodes is the curve's generation 0, so movement counts from
  where the learner began;
- per method: the mean slope over seeds with a t-interval, the first and the last
  generation's figure, and the standard deviation between seeds of the last;
- the controls of the paper's question, per trial: how many candidates joined the
  population (`accepted`) and how many of those at η 0 (no member preferred them: they
  joined on a tie of ranks), its last size, and the largest `phi_tv` (how far the φ used ever
  departed from the rival rule's: 0 means hola trained as hola_r would have);
- the paired difference A − B of the last generation's figure, seed by seed (trials of one
  seed share the population build and the validation episodes), its standard deviation,
  and the power calculation: the seeds n for which the paired 95 % t-interval's half-width
  t(0.975, n − 1) · sd / √n is at most `--half-width`, and the smallest difference such a
  design detects at 80 % power, (t(0.975) + t(0.8)) · sd / √n.

A validation figure is a mean over `validation.episodes` episodes, so the spread between
seeds already holds that binomial noise; an evaluation with more episodes per learner has
less of it, and the seeds computed here are an upper bound on that count.

Prints one JSON line and writes `<out>/movement.json` and `<out>/movement.png` (the curves).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

TRIAL = re.compile(r"^(?P<method>.+)-s(?P<seed>\d+)$")


def trials(folder: Path) -> list[tuple[str, int, list[dict[str, str]]]]:
    """(method, seed, the metrics rows of generations ≥ 1) of every trial that has any."""
    out = []
    for trial in sorted((folder / "trials").iterdir()):
        match = TRIAL.match(trial.name)
        path = trial / "metrics.csv"
        if match is None or not path.is_file():
            continue
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f) if int(r["generation"]) >= 1]
        if rows:
            out.append((match["method"], int(match["seed"]), rows))
    return out


def curves(folder: Path, key: str) -> dict[str, dict[int, list[tuple[int, float]]]]:
    """method → seed → [(generation, figure)] over generations ≥ 1 that have the figure."""
    out: dict[str, dict[int, list[tuple[int, float]]]] = {}
    for method, seed, rows in trials(folder):
        points = [
            (int(r["generation"]), float(r[key])) for r in rows if r.get(key) not in (None, "")
        ]
        if points:
            out.setdefault(method, {})[seed] = points
    return out


def controls(folder: Path) -> dict[str, dict[str, dict[str, float]]]:
    """method → seed → candidates joined, how many of them no member preferred (η 0: joined
    on a tie of ranks), last population size, and the largest phi_tv (against the rival
    rule's φ) and phi_tv_uniform (against uniform draws; nan for runs made before it)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for method, seed, rows in trials(folder):
        tv = column(rows, "phi_tv")
        joins = [r for r in rows if r.get("accepted") not in (None, "") and float(r["accepted"])]
        out.setdefault(method, {})[str(seed)] = {
            "joined": float(len(joins)),
            "joined_at_eta_0": float(sum(float(r.get("eta") or 0.0) == 0.0 for r in joins)),
            "population_size": (column(rows, "population_size") or [math.nan])[-1],
            "phi_tv_max": max(tv) if tv else math.nan,
            "phi_tv_uniform_max": max(flat)
            if (flat := column(rows, "phi_tv_uniform"))
            else math.nan,
        }
    return out


def start_figures(folder: Path, key: str) -> dict[int, float]:
    """seed → `key` of the trials' common start, played as a trial's validation plays its
    learner (the seed's validation episodes); empty when the trials have no start."""
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.generation_zero import start_member
    from hola_ray.methods.monitors import validation

    out: dict[int, float] = {}
    for trial in sorted((folder / "trials").iterdir()):
        match = TRIAL.match(trial.name)
        if match is None or int(match["seed"]) in out or not (trial / "config.yaml").is_file():
            continue
        config = RunConfig.from_yaml(trial / "config.yaml")
        if config.pretrain.start_agent == "none":
            continue
        donor, _, entry = start_member(config)
        out[config.seed] = validation(config, donor.load_member_export(entry["node"]))[key]
    return out


def column(rows: list[dict[str, str]], key: str) -> list[float]:
    """A metrics column's values, the rows without it left out."""
    return [float(r[key]) for r in rows if r.get(key) not in (None, "")]


def slope(points: list[tuple[int, float]]) -> tuple[float, float]:
    """Least-squares slope of figure on generation, and its standard error (nan with fewer
    than three points)."""
    g = np.array([p[0] for p in points], dtype=np.float64)
    y = np.array([p[1] for p in points], dtype=np.float64)
    if g.size < 2:
        return float("nan"), float("nan")
    fit = stats.linregress(g, y)
    return float(fit.slope), float(fit.stderr) if g.size > 2 else float("nan")


def t_interval(values: np.ndarray) -> dict[str, float]:
    """Mean, standard deviation and 95 % t-interval of values (seeds as the unit)."""
    n = values.size
    mean = float(values.mean())
    sd = float(values.std(ddof=1)) if n > 1 else float("nan")
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else float("nan")
    return {"n": n, "mean": mean, "sd": sd, "ci95": [mean - half, mean + half]}


def seeds_needed(sd: float, half_width: float, most: int = 1000) -> int | None:
    """The fewest seeds n ≥ 2 whose paired 95 % t-interval is at most ±half_width."""
    for n in range(2, most + 1):
        if stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n) <= half_width:
            return n
    return None


def detectable(sd: float, n: int, power: float = 0.8) -> float:
    """The smallest true difference a paired two-sided 5 % t-test on n seeds finds with
    probability `power`."""
    return float((stats.t.ppf(0.975, n - 1) + stats.t.ppf(power, n - 1)) * sd / math.sqrt(n))


def summarise(
    found: dict[str, dict[int, list[tuple[int, float]]]], a: str, b: str, half_width: float
) -> dict[str, Any]:
    methods: dict[str, Any] = {}
    for method, seeds in found.items():
        per_seed = {s: slope(p) for s, p in seeds.items()}
        slopes = np.array([v[0] for v in per_seed.values()])
        first = np.array([p[0][1] for p in seeds.values()])
        last = np.array([p[-1][1] for p in seeds.values()])
        methods[method] = {
            "seeds": sorted(seeds),
            "generations": max(p[-1][0] for p in seeds.values()),
            "slope_by_seed": {str(s): {"slope": v[0], "se": v[1]} for s, v in per_seed.items()},
            "slope": t_interval(slopes),
            "first": t_interval(first),
            "last": t_interval(last),
            "moved": t_interval(last - first),
        }
    out: dict[str, Any] = {"methods": methods}
    if a in found and b in found:
        shared = sorted(set(found[a]) & set(found[b]))
        diffs = np.array([found[a][s][-1][1] - found[b][s][-1][1] for s in shared])
        paired = t_interval(diffs)
        needed = seeds_needed(paired["sd"], half_width) if len(shared) > 1 else None
        out["paired"] = {
            "a": a,
            "b": b,
            "seeds": shared,
            "last_difference": paired,
            "half_width_goal": half_width,
            "seeds_needed": needed,
            "detectable_at_80pct": {
                str(n): detectable(paired["sd"], n) for n in (4, 6, 8, 10, 12) if len(shared) > 1
            },
        }
    return out


def plot(found: dict[str, dict[int, list[tuple[int, float]]]], key: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (method, seeds) in enumerate(sorted(found.items())):
        for n, (seed, points) in enumerate(sorted(seeds.items())):
            g, y = zip(*points, strict=True)
            label = method if n == 0 else None
            ax.plot(g, y, color=colours[k % len(colours)], alpha=0.7, marker=".", label=label)
            ax.annotate(f"s{seed}", (g[-1], y[-1]), fontsize=7)
    ax.set_xlabel("generation")
    ax.set_ylabel(f"{key} (validation teammates)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("experiment", type=Path)
    parser.add_argument("--a", default="hola")
    parser.add_argument("--b", default="uniform")
    parser.add_argument("--key", default="val_success")
    parser.add_argument("--half-width", type=float, default=0.06)
    parser.add_argument(
        "--with-start", action="store_true", help="the common start as generation 0 of each curve"
    )
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    found = curves(args.experiment, args.key)
    if not found:
        parser.error(f"{args.experiment}: no trial with {args.key} in its metrics.csv")
    if args.with_start:
        starts = start_figures(args.experiment, args.key)
        for seeds in found.values():
            for seed, points in seeds.items():
                if seed in starts:
                    points.insert(0, (0, starts[seed]))
    result = {"experiment": str(args.experiment), "key": args.key, "with_start": args.with_start}
    result |= summarise(found, args.a, args.b, args.half_width)
    result["controls"] = controls(args.experiment)
    out = args.out or args.experiment
    out.mkdir(parents=True, exist_ok=True)
    result = json.loads(json.dumps(result).replace("NaN", "null"))  # strict JSON
    (out / "movement.json").write_text(json.dumps(result, indent=1))
    plot(found, args.key, out / "movement.png")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
