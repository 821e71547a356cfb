"""The comparison plan's analysis: builds as the unit, Holm's steps and intervals, the fixed
verdict rule, and the checks (competence, levelled curves, φ's departure), on made-up
figures whose answers are worked by hand."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from scipy import stats

from hola_ray.config.reader import ConfigError
from hola_ray.experiment import plan as P

PLAN = P.Plan(
    experiment="configs/experiments/none.yaml",
    reference="hola",
    baselines=("ahead", "same", "noisy", "behind"),
    pool="het",
    figure="success",
    builds=4,
    seeds_per_build=2,
    margin=0.10,
    alpha=0.05,
    tie_width=0.12,
    level_generations=3,
    competence_each=0.5,
    competence_median=0.6,
    phi_departure=0.05,
)
SEEDS = tuple(range(8))  # build of seed s: s % 4


def figures() -> dict[str, float]:
    """hola at 0.70 + a build effect; `ahead` 0.15 below it on every build, `same` within
    half a point, `noisy` ±20 points, `behind` 5 points above."""
    build = [0.0, 0.03, -0.02, 0.01]
    wobble = [0.004, -0.004, 0.002, -0.002]
    out = {}
    for s in SEEDS:
        b = s % 4
        hola = 0.70 + build[b] + (0.01 if s < 4 else -0.01)
        out[f"hola-s{s}"] = hola
        out[f"ahead-s{s}"] = hola - 0.15 + wobble[b]
        out[f"same-s{s}"] = hola + wobble[b]
        out[f"noisy-s{s}"] = hola + (0.2 if b % 2 else -0.2) + wobble[b]
        out[f"behind-s{s}"] = hola + 0.05 + wobble[b]
    return out


def test_holm_steps_levels_and_adjusted_p_by_hand():
    out = P.holm({"a": 0.01, "b": 0.04, "c": 0.03}, 0.05)
    assert [out[n]["step"] for n in "acb"] == [1, 2, 3]
    assert out["a"]["rejected"] and out["a"]["alpha"] == pytest.approx(0.05 / 3)
    assert not out["c"]["rejected"] and out["c"]["alpha"] == pytest.approx(0.05 / 2)
    # after the first failure every later step keeps its level and is not rejected, even
    # though 0.04 alone would pass the third step's 0.05
    assert not out["b"]["rejected"] and out["b"]["alpha"] == pytest.approx(0.05 / 2)
    assert [out[n]["p_adjusted"] for n in "acb"] == pytest.approx([0.03, 0.06, 0.06])
    assert P.holm_adjusted({"a": 0.01, "b": 0.04, "c": 0.03}) == pytest.approx(
        {"a": 0.03, "b": 0.06, "c": 0.06}
    )


def test_the_verdict_rule():
    assert P.verdict(0.11, 0.2, 0.10, 0.12) == "ahead by the margin"
    assert P.verdict(0.01, 0.3, 0.10, 0.12) == "ahead"  # wide, but clear of 0
    assert P.verdict(-0.3, -0.01, 0.10, 0.12) == "behind"
    assert P.verdict(-0.06, 0.06, 0.10, 0.12) == "tie"
    assert P.verdict(-0.07, 0.06, 0.10, 0.12) == "inconclusive"


def test_builds_are_the_unit_and_each_baseline_gets_its_verdict():
    out = P.compare_builds(figures(), PLAN, SEEDS)
    assert {x: c["verdict"] for x, c in out.items()} == {
        "ahead": "ahead by the margin",
        "same": "tie",
        "noisy": "inconclusive",
        "behind": "behind",
    }
    # `same`: the build means' differences are −wobble (the seeds' ±0.01 cancel in a build)
    same = out["same"]
    d = -np.array([0.004, -0.004, 0.002, -0.002])
    assert same["builds"] == 4 and same["mean"] == pytest.approx(d.mean(), abs=1e-12)
    assert same["se"] == pytest.approx(d.std(ddof=1) / 2)
    level = same["level"]
    half = stats.t.ppf(1 - (1 - level) / 2, 3) * same["se"]
    assert same["interval"] == pytest.approx([d.mean() - half, d.mean() + half])
    # Holm: the largest p (same or noisy) is tested last; every level is α / (k − i + 1)
    # or the first failing step's
    levels = sorted((c["holm_step"], c["level"]) for c in out.values())
    assert levels[0] == (1, pytest.approx(1 - 0.05 / 4))
    assert all(lv <= 1 - 0.05 / 4 + 1e-12 or lv >= 1 - 0.05 / 3 - 1e-12 for _, lv in levels)
    ahead = out["ahead"]
    assert ahead["p_margin"] < 0.05 and ahead["p_ahead"] < 1e-4


def test_a_build_counts_only_with_every_seed_in():
    f = figures()
    del f["hola-s5"]  # build 1 loses a seed of hola
    means = P.build_means(f, "hola", PLAN, SEEDS)
    assert sorted(means) == [0, 2, 3]
    assert P.compare_builds(f, PLAN, SEEDS)["same"]["builds"] == 3


def test_the_seeds_must_fill_every_build_alike():
    PLAN.check_seeds(SEEDS)
    with pytest.raises(ConfigError, match=r"\[2, 2, 2, 1\] seeds, not 2 each"):
        PLAN.check_seeds(SEEDS[:7])


def metrics_rows(values, accepted=(), eta=0.25, phi=0.2):
    rows = [{"generation": "0", "val_success": "", "accepted": "", "eta": "", "phi_tv": ""}]
    for g, v in enumerate(values, start=1):
        joined = g in accepted
        rows.append(
            {
                "generation": str(g),
                "val_success": str(v),
                "accepted": "1" if joined else "0",
                "eta": str(eta if joined else 0.0),
                "phi_tv": str(phi if g > 2 else 0.0),
                "phi_tv_uniform": "0.3",
            }
        )
    return rows


def test_late_slope_levelled_and_joins():
    assert P.late_slope(metrics_rows([0.5, 0.6, 0.7, 0.8]), 3) == pytest.approx(0.1)
    assert P.late_slope(metrics_rows([0.5, 0.6]), 3) is None
    rising = {f"hola-s{s}": metrics_rows([0.5, 0.6, 0.7 + s / 1e3, 0.8]) for s in SEEDS}
    flat = {f"same-s{s}": metrics_rows([0.5, 0.7, 0.7 + 0.01 * (-1) ** s, 0.7]) for s in SEEDS}
    out = P.levelled({**rising, **flat}, PLAN, SEEDS, ["hola", "same"])
    assert not out["hola"]["levelled"] and out["same"]["levelled"]
    j = P.joins(metrics_rows([0.5, 0.6, 0.7, 0.8], accepted=(2, 4)))
    assert j == {
        "joins": 2,
        "eta": [0.25, 0.25],
        "generations": 4,
        "phi_tv_max": 0.2,
        "phi_tv_uniform_max": 0.3,
    }


def test_competence_each_and_median():
    f = figures()
    assert P.competence(f, PLAN)["met"]
    f["hola-s3"] = 0.4
    c = P.competence(f, PLAN)
    assert not c["met"] and c["below"] == ["hola-s3"] and math.isclose(c["lowest"], 0.4)


def test_the_analysis_end_to_end_writes_its_verdicts(tmp_path):
    f = figures()
    trials = {t: {"pools": {"het": {"success": v}}} for t, v in f.items()}
    scale = {
        "floor": {"success": 0.5},
        "ceilings": {"handwritten": {"success": 0.85}},
        "normalised": {"handwritten": {"mean": 0.57}},
    }
    methods = {"hola": {"het": {"success": 0.7, "scale": scale}}}
    (tmp_path / "results.json").write_text(json.dumps({"trials": trials, "methods": methods}))
    for t in f:
        folder = tmp_path / "trials" / t
        folder.mkdir(parents=True)
        rows = metrics_rows([0.6, 0.7, 0.7, 0.7], accepted=(3,))
        with (folder / "metrics.csv").open("w", newline="") as out:
            w = csv.DictWriter(out, fieldnames=list(rows[1]))
            w.writeheader()
            w.writerows(rows)
    a = P.analyse(PLAN, tmp_path, SEEDS)
    assert not a["stopped_short"] and a["phi_departs_everywhere"]
    assert a["competence"]["met"] and all(v["levelled"] for v in a["levelled"].values())
    text = P.plan_table(a)
    assert "**ahead by the margin**" in text and "**tie**" in text and "**behind**" in text
    assert "| hola | 70.0 | 50.0 | handwritten 85.0 | handwritten 0.57 |" in text
    del trials["behind-s0"]
    (tmp_path / "results.json").write_text(json.dumps({"trials": trials, "methods": methods}))
    short = P.analyse(PLAN, tmp_path, SEEDS)
    assert short["stopped_short"] and short["builds_complete"]["behind"] == 3
    assert "Stopped short of the plan" in P.plan_table(short)


def test_the_committed_plan_reads_and_its_seeds_fill_its_builds():
    """The plan of the comparison at competence names its experiment, whose seeds give each
    of the plan's builds its seeds and whose population template takes seed mod builds."""
    from hola_ray.experiment.config import Experiment
    from hola_ray.homes import ROOT

    plan = P.Plan.from_yaml(ROOT / "configs/experiments/competence-comparison-3v2.plan.yaml")
    experiment = Experiment.from_yaml(ROOT / plan.experiment)
    plan.check_seeds(experiment.seeds)
    assert set(experiment.methods) == {plan.reference, *plan.baselines}
    template = experiment.overrides["pretrain"]["population"]
    assert template.endswith(f"{{seed%{plan.builds}}}")
    assert experiment.overrides["population"]["preferred_only"] is True
