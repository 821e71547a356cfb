"""What an experiment costs: measured trials → the wall time of every trial on N nodes.

    python benchmarks/cost_model.py RUN_DIR [RUN_DIR ...]
        [--experiment configs/experiments/paper.yaml] [--calib 1.5]
        [--node-cpus 16] [--nodes 1 5] [--out FILE]

Each RUN_DIR is a run (or an experiment's trial) measured on this machine; `--calib` is
`benchmarks/calib.py`'s scale of the machine it ran on (the reference machine's seconds ÷
this machine's, for the same work), so every figure below is in reference-machine seconds.
From the runs' `metrics.csv` the model reads, per run: generation 0's wall time, its
pre-training's time and env steps, and the mean wall time and Oracle time of a generation
≥ 1 with its learner transitions. A trial of the experiment then costs

    start + generation 0 (its pre-training scaled by its env steps, the rest as measured)
    + G × a generation (its Oracle scaled by what the experiment's `oracle.budget` counts,
    the learner's transitions or env steps, per generation; the rest — Grapher,
    validation, judges, commit — as measured),

so a run measured at the experiment's own settings with fewer env steps (a shorter Oracle
and pre-training) prices the full budget without scaling the per-generation work that does
not grow with it; a run whose rows lack `oracle_s` / `pretrain_s` has its whole generation
(or generation 0) scaled, an upper bound. With the rates of the measured run of the same
method if there is one, else of the first run (say which in `basis`). Self-play trains no
population and weighs no hyperedges: with a measured sp run it has its own rates, else it
is charged as the first run (an upper bound).

The cluster: a trial holds `1 + oracle.env_runners` CPUs (`ExperimentRunner.bundles`), so a
node of `--node-cpus` CPUs holds ⌊cpus ÷ that⌋ trials side by side; trials are started in
waves as CPUs free up, longest first. Each CPU is assumed to run at the reference machine's
speed (the calibration measured a laptop's core, not the cluster's: a measured node's own
scale replaces the assumption), and the Grapher's evaluation actors, which ask for no CPU,
share their trial's.

Prints one JSON line per trial and the totals; `--out` writes them all as one JSON file.
"""

from __future__ import annotations

import argparse
import csv
import heapq
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Measured:
    """One measured run's rates, in reference-machine seconds."""

    path: Path
    method: str
    start_s: float
    """before generation 0's row: the command's start (`time_process_s` of row 0)"""
    zero_s: float
    """generation 0's wall time, the start excluded"""
    pretrain_env_steps: float
    generation_s: float
    """mean wall time of a generation ≥ 1"""
    samples_per_generation: float
    """mean learner transitions of a generation ≥ 1"""
    env_steps_per_generation: float = 0.0
    """the env steps of a generation ≥ 1 (what a budget of `env_steps` counts; the learner's
    own transitions, `samples_per_generation`, are what `learner_samples` counts)"""
    oracle_s: float | None = None
    """mean Oracle time of a generation ≥ 1 (the part that scales with the learner's
    transitions); None: not recorded, the whole generation scales"""
    pretrain_s: float | None = None
    """generation 0's pre-training time (the part that scales with its env steps); None:
    not recorded, the whole of generation 0 scales"""

    @classmethod
    def read(cls, path: Path, calib: float) -> Measured:
        import yaml

        with open(path / "metrics.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows:
            raise SystemExit(f"{path}: no metrics rows")
        config = yaml.safe_load((path / "config.yaml").read_text())
        zero = rows[0] if int(rows[0]["generation"]) == 0 else None
        later = [r for r in rows if int(r["generation"]) >= 1]
        if not later:
            raise SystemExit(f"{path}: no generation ≥ 1 to measure a generation by")

        def num(row: dict[str, str] | None, key: str) -> float:
            value = (row or {}).get(key, "")
            return float(value) if value not in ("", None) else 0.0

        start = num(zero or later[0], "time_process_s")

        def per_generation(key: str) -> float:  # the mean increment of a cumulative column
            steps, before = [], 0.0
            for r in rows:
                total = num(r, key)
                if int(r["generation"]) >= 1:
                    steps.append(total - before)
                before = total
            return sum(steps) / len(steps)

        def recorded(row: dict[str, str] | None, key: str) -> bool:
            return (row or {}).get(key, "") not in ("", None)

        split = all(recorded(r, "oracle_s") for r in later)
        return cls(
            path=path,
            method=config["method"],
            start_s=start * calib,
            zero_s=max(0.0, num(zero, "wall_s") - start) * calib,
            pretrain_env_steps=num(zero, "pretrain_env_steps"),
            generation_s=sum(num(r, "wall_s") for r in later) / len(later) * calib,
            samples_per_generation=per_generation("learner_samples"),
            env_steps_per_generation=per_generation("env_steps"),
            oracle_s=sum(num(r, "oracle_s") for r in later) / len(later) * calib if split else None,
            pretrain_s=num(zero, "pretrain_s") * calib if recorded(zero, "pretrain_s") else None,
        )


def trial_seconds(config, basis: Measured) -> dict[str, float]:
    """A trial of `config` in reference seconds, from a measured run's rates."""
    zero = 0.0
    if config.pretrain.population == "none" and not config.strategy.trains_alone():
        steps = basis.pretrain_env_steps
        scale = config.pretrain.env_steps / steps if steps else 1.0
        grows = basis.zero_s if basis.pretrain_s is None else min(basis.pretrain_s, basis.zero_s)
        zero = basis.zero_s - grows + grows * scale
    grows = basis.generation_s if basis.oracle_s is None else basis.oracle_s
    measured = (
        basis.env_steps_per_generation
        if config.oracle.budget == "env_steps"
        else basis.samples_per_generation
    )
    if measured <= 0:
        raise SystemExit(
            f"{basis.path}: no {config.oracle.budget} recorded per generation, which "
            "the experiment's oracle.budget counts"
        )
    scale = config.oracle.env_steps / measured
    per_generation = basis.generation_s - grows + grows * scale
    return {
        "start_s": basis.start_s,
        "generation_0_s": zero,
        "generations_s": config.generations * per_generation,
        "total_s": basis.start_s + zero + config.generations * per_generation,
    }


def waves(durations: list[float], slots: int) -> float:
    """The wall time of trials of `durations` on `slots` side by side, longest first, each
    starting when a slot frees (list scheduling)."""
    if not durations:
        return 0.0
    ends = [0.0] * max(1, slots)
    for d in sorted(durations, reverse=True):
        heapq.heapreplace(ends, ends[0] + d)
    return max(ends)


def model(
    experiment_path: Path,
    measured: list[Measured],
    node_cpus: int,
    nodes: list[int],
) -> dict[str, Any]:
    from hola_ray.experiment.config import Experiment

    exp = Experiment.from_yaml(experiment_path)
    by_method = {m.method: m for m in measured}
    trials, durations, cpus = [], [], set()
    for name in exp.trials():
        config = exp.run_config(name)
        basis = by_method.get(config.method, measured[0])
        cost = trial_seconds(config, basis)
        need = 1 + config.oracle.env_runners
        cpus.add(need)
        trials.append({"trial": name, "cpus": need, "basis": str(basis.path), **cost})
        durations.append(cost["total_s"])
    per_node = {n: max(1, node_cpus // max(cpus)) * n for n in nodes}
    return {
        "experiment": str(experiment_path),
        "trials": trials,
        "trial_hours_sum": round(sum(durations) / 3600, 2),
        "node_cpus": node_cpus,
        "wall_hours": {str(n): round(waves(durations, per_node[n]) / 3600, 2) for n in nodes},
        "trials_side_by_side": {str(n): per_node[n] for n in nodes},
        "assumes": "each CPU at the reference machine's speed; evaluation actors share "
        "their trial's CPUs",
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument(
        "--experiment", type=Path, default=ROOT / "configs" / "experiments" / "paper.yaml"
    )
    parser.add_argument("--calib", type=float, default=1.0, help="calib.py's scale")
    parser.add_argument("--node-cpus", type=int, default=16, help="c5.4xlarge: 16")
    parser.add_argument("--nodes", type=int, nargs="+", default=[1, 5])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    if args.calib <= 0 or not math.isfinite(args.calib):
        parser.error("--calib must be a positive number")
    measured = [Measured.read(p, args.calib) for p in args.runs]
    result = model(args.experiment, measured, args.node_cpus, args.nodes)
    for t in result["trials"]:
        print(json.dumps({k: round(v, 1) if isinstance(v, float) else v for k, v in t.items()}))
    print(json.dumps({k: v for k, v in result.items() if k != "trials"}))
    if args.out:
        args.out.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
