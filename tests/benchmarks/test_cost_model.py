"""benchmarks/cost_model.py: measured runs → a trial's cost and an experiment's wall time."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import pytest
import yaml

from hola_ray.experiment.config import Experiment

ROOT = Path(__file__).parents[2]
_spec = importlib.util.spec_from_file_location("cost_model", ROOT / "benchmarks" / "cost_model.py")
cost_model = importlib.util.module_from_spec(_spec)
sys.modules["cost_model"] = cost_model  # its dataclass looks its module up
_spec.loader.exec_module(cost_model)


def write_run(folder: Path, method: str, rows: list[dict]) -> Path:
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(yaml.safe_dump({"method": method}))
    keys = sorted({k for r in rows for k in r})
    with open(folder / "metrics.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    return folder


def test_a_measured_run_in_reference_seconds(tmp_path):
    run = write_run(
        tmp_path / "hola",
        "hola",
        [
            {"generation": 0, "wall_s": 30, "time_process_s": 10, "pretrain_env_steps": 1000},
            {"generation": 1, "wall_s": 20, "learner_samples": 100},
            {"generation": 2, "wall_s": 40, "learner_samples": 300},
        ],
    )
    m = cost_model.Measured.read(run, calib=0.5)
    assert (m.start_s, m.zero_s, m.pretrain_env_steps) == (5.0, 10.0, 1000.0)
    assert (m.generation_s, m.samples_per_generation) == (15.0, 150.0)


def test_an_experiment_costed_from_a_run_and_scheduled_on_nodes(tmp_path):
    run = write_run(
        tmp_path / "hola",
        "hola",
        [
            {"generation": 0, "wall_s": 100, "pretrain_env_steps": 50_000},
            {"generation": 1, "wall_s": 60, "learner_samples": 100_000},
        ],
    )
    measured = [cost_model.Measured.read(run, calib=1.0)]
    exp = ROOT / "configs" / "experiments" / "laptop-3v2.yaml"  # 7 methods × 3 seeds
    out = cost_model.model(exp, measured, node_cpus=4, nodes=[1, 2])
    by = {t["trial"]: t for t in out["trials"]}
    # hola pre-trains 1 M env steps (20 × the measured 50 k), 6 generations of 100 k
    assert by["hola-s0"]["generation_0_s"] == pytest.approx(100 * 20)
    assert by["hola-s0"]["generations_s"] == pytest.approx(6 * 60)
    assert by["sp-s0"]["generation_0_s"] == 0.0  # self-play trains no population
    assert out["trials_side_by_side"] == {"1": 2, "2": 4}  # 2 CPUs a trial
    assert out["wall_hours"]["2"] < out["wall_hours"]["1"] <= out["trial_hours_sum"]


def test_only_the_oracle_and_the_pretraining_scale_with_the_budget(tmp_path):
    """A run measured with a shorter Oracle and pre-training: the Grapher, validation and
    the rest of each generation are charged as measured, not multiplied with the budget."""
    rows = [
        {"generation": 0, "wall_s": 100, "pretrain_env_steps": 50_000, "pretrain_s": 80},
        {"generation": 1, "wall_s": 60, "oracle_s": 40, "learner_samples": 100_000},
        {"generation": 2, "wall_s": 80, "oracle_s": 60, "learner_samples": 200_000},
    ]
    split = cost_model.Measured.read(write_run(tmp_path / "split", "hola", rows), calib=1.0)
    assert (split.oracle_s, split.pretrain_s, split.generation_s) == (50.0, 80.0, 70.0)
    whole = cost_model.Measured.read(
        write_run(
            tmp_path / "whole",
            "hola",
            [{k: v for k, v in r.items() if k not in ("oracle_s", "pretrain_s")} for r in rows],
        ),
        calib=1.0,
    )
    assert (whole.oracle_s, whole.pretrain_s) == (None, None)
    exp = ROOT / "configs" / "experiments" / "laptop-3v2.yaml"  # 1 M pre-training, 6 × 100 k
    config = Experiment.from_yaml(exp).run_config("hola-s0")
    got, upper = cost_model.trial_seconds(config, split), cost_model.trial_seconds(config, whole)
    # 20 × the pre-training's 80 s plus the 20 s it did not spend pre-training
    assert got["generation_0_s"] == pytest.approx(20 * 80 + 20)
    assert upper["generation_0_s"] == pytest.approx(20 * 100)
    # 100 k transitions a generation, as measured: 50 s of Oracle for 100 k, plus 20 s
    assert got["generations_s"] == pytest.approx(6 * (50 * 100_000 / 100_000 + 20))
    assert got["total_s"] <= upper["total_s"]


def test_the_oracle_scales_by_what_the_experiments_budget_counts(tmp_path):
    """paper.yaml's budget counts env steps (1 M a generation), the 3 vs 2 comparison's the
    learner's own transitions (1 M a generation): a run measured with both is scaled by each
    experiment's own count."""
    rows = [
        {"generation": 0, "wall_s": 10, "env_steps": 0},
        {"generation": 1, "wall_s": 30, "oracle_s": 20, "env_steps": 300, "learner_samples": 100},
        {"generation": 2, "wall_s": 30, "oracle_s": 20, "env_steps": 600, "learner_samples": 200},
    ]
    run = cost_model.Measured.read(write_run(tmp_path / "hola", "hola", rows), calib=1.0)
    assert (run.env_steps_per_generation, run.samples_per_generation) == (300.0, 100.0)
    experiments = ROOT / "configs" / "experiments"
    paper = Experiment.from_yaml(experiments / "paper.yaml").run_config("hola-s0")
    assert (paper.oracle.budget, paper.oracle.env_steps) == ("env_steps", 1_000_000)
    ours = Experiment.from_yaml(experiments / "comparison-3v2.yaml").run_config("hola-s1")
    assert (ours.oracle.budget, ours.oracle.env_steps) == ("learner_samples", 1_000_000)
    per_paper = cost_model.trial_seconds(paper, run)["generations_s"] / paper.generations
    per_ours = cost_model.trial_seconds(ours, run)["generations_s"] / ours.generations
    assert per_paper == pytest.approx(10 + 20 * 1_000_000 / 300)
    assert per_ours == pytest.approx(10 + 20 * 1_000_000 / 100)


def test_waves_schedule_the_longest_first():
    assert cost_model.waves([3, 3, 2, 2, 2], 2) == 7  # 3 + 2 + 2 on one slot, 3 + 2 on the other
    assert cost_model.waves([5, 1, 1, 1], 2) == 5
    assert cost_model.waves([], 3) == 0
