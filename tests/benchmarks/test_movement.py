"""benchmarks/movement.py: slopes, the spread between seeds and the seeds a paired
interval needs, on an experiment directory of known curves."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location(
    "movement", Path(__file__).parents[2] / "benchmarks" / "movement.py"
)
movement = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(movement)


def write_trial(folder: Path, name: str, figures: list[float]) -> None:
    trial = folder / "trials" / name
    trial.mkdir(parents=True)
    with open(trial / "metrics.csv", "w", newline="") as f:
        w = csv.DictWriter(f, ["generation", "val_success"])
        w.writeheader()
        w.writerow({"generation": 0, "val_success": ""})  # generation 0 has no learner
        for g, y in enumerate(figures, start=1):
            w.writerow({"generation": g, "val_success": y})


def test_slopes_spread_and_seeds_needed(tmp_path):
    # hola rises 0.05 a generation from 0.2 + seed noise; uniform 0.03 a generation
    offsets = [0.0, 0.02, -0.01, 0.03]
    lifts = [0.04, 0.06, 0.02, 0.08]  # hola − uniform at the last generation, per seed
    for s, (o, lift) in enumerate(zip(offsets, lifts, strict=True)):
        uniform = [0.2 + o + 0.03 * g for g in range(5)]
        hola = [0.2 + o + 0.05 * g for g in range(4)] + [uniform[-1] + lift]
        write_trial(tmp_path, f"hola-s{s}", hola)
        write_trial(tmp_path, f"uniform-s{s}", uniform)
    assert movement.main([str(tmp_path), "--half-width", "0.06"]) == 0
    result = json.loads((tmp_path / "movement.json").read_text())
    assert (tmp_path / "movement.png").stat().st_size > 0
    uniform = result["methods"]["uniform"]
    assert uniform["slope"]["mean"] == pytest.approx(0.03)
    assert uniform["slope"]["sd"] == pytest.approx(0.0, abs=1e-12)
    assert uniform["moved"]["mean"] == pytest.approx(0.12)
    assert uniform["last"]["sd"] == pytest.approx(np.std([0.32 + o for o in offsets], ddof=1))
    paired = result["paired"]
    assert paired["seeds"] == [0, 1, 2, 3]
    assert paired["last_difference"]["mean"] == pytest.approx(np.mean(lifts))
    sd = float(np.std(lifts, ddof=1))
    assert paired["last_difference"]["sd"] == pytest.approx(sd)
    n = paired["seeds_needed"]
    from scipy import stats

    def half(k: int) -> float:
        return stats.t.ppf(0.975, k - 1) * sd / math.sqrt(k)

    assert half(n) <= 0.06 < half(n - 1) or n == 2
    detect = paired["detectable_at_80pct"]
    assert detect["4"] > detect["6"] > detect["12"] > 0


def test_a_wide_spread_needs_more_seeds():
    assert movement.seeds_needed(0.05, 0.06) < movement.seeds_needed(0.15, 0.06)
    assert movement.seeds_needed(10.0, 0.06, most=50) is None


def test_controls_count_joins_and_the_largest_phi_departure(tmp_path):
    """Per trial: candidates that joined, those of them at η 0, the last population size and
    the largest phi_tv and phi_tv_uniform (generation 0, which has no candidate, left out)."""
    trial = tmp_path / "trials" / "hola-s3"
    trial.mkdir(parents=True)
    rows = [
        {"generation": 0, "accepted": "", "eta": "", "population_size": 4, "phi_tv": ""},
        {"generation": 1, "accepted": 0, "eta": 0.0, "population_size": 4, "phi_tv": 0.0},
        {"generation": 2, "accepted": 1, "eta": 0.0, "population_size": 5, "phi_tv": 0.004},
        {"generation": 3, "accepted": 1, "eta": 0.25, "population_size": 6, "phi_tv": 0.031},
    ]
    for row, uniform in zip(rows, ("", 0.1, 0.2, 0.15), strict=True):
        row["phi_tv_uniform"] = uniform
    with open(trial / "metrics.csv", "w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert movement.controls(tmp_path) == {
        "hola": {
            "3": {
                "joined": 2.0,
                "joined_at_eta_0": 1.0,
                "population_size": 6.0,
                "phi_tv_max": 0.031,
                "phi_tv_uniform_max": 0.2,
            }
        }
    }


def test_with_start_the_common_start_is_each_curves_generation_zero(tmp_path, monkeypatch):
    """`--with-start`: each seed's curve begins at its trials' common start, played with the
    seed's validation episodes (the play replaced here: the wiring is what is tested), so
    the slope counts from where the learners began."""
    import yaml

    from hola_ray.commands.run import DEFAULT
    from hola_ray.methods import monitors
    from hola_ray.methods.config import RunConfig

    config = RunConfig.from_dict(DEFAULT)  # fcp-3v1-s0 (the start) fits its layout
    played = []

    def fake_validation(c, export):
        played.append((c.seed, sorted(export)))
        return {"val_success": 0.1 * c.seed}

    monkeypatch.setattr(monitors, "validation", fake_validation)
    for seed in (1, 2):
        write_trial(tmp_path, f"hola-s{seed}", [0.5, 0.6])
        data = config.to_dict() | {"seed": seed}
        data["pretrain"] = data["pretrain"] | {"start_agent": "fcp-3v1-s0"}
        (tmp_path / "trials" / f"hola-s{seed}" / "config.yaml").write_text(yaml.safe_dump(data))
    assert movement.main([str(tmp_path), "--with-start"]) == 0
    result = json.loads((tmp_path / "movement.json").read_text())
    assert [s for s, _ in played] == [1, 2] and result["with_start"]
    hola = result["methods"]["hola"]
    assert hola["first"]["mean"] == pytest.approx(0.15)  # the starts, 0.1 and 0.2
    assert hola["moved"]["mean"] == pytest.approx(0.6 - 0.15)
