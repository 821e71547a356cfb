"""An experiment's third phase: what each trial's training took (`budget_spent`) and the
files its evaluation ends in (`write_results`: results.json, results.md, figure.png)."""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hola_ray.experiment.config import Experiment, parse_trial
from hola_ray.experiment.results import (
    _atomic_json,
    aggregate,
    builds_check,
    builds_table,
    results_table,
    verdict_sentence,
)

INTERVALS = (
    "95 %, stratified bootstrap: training seeds within each method, one resample shared by "
    "methods with the same seeds (paired by seed), episodes within each partner "
    "combination, shared by every trial (paired)"
)
"""How results.json's intervals are made, written beside them."""


def budget_spent(root: Path) -> dict[str, Any]:
    """What a trial's training took: env steps, the learner's own transitions and
    gradient steps (cumulative, at its last generation), pre-training env steps, the
    wall time of all its generations (`train_s`, generation 0's population build
    included) and of the learner's own (`learner_train_s`: generations 1 on), and for
    a method with a rival rule the largest distance between its φ and the rival's
    (`phi_tv_max`)."""
    from hola_ray.experiment.tasks import RESTORED
    from hola_ray.population.rundir import RunDir, phi_departure

    if (root / RESTORED).is_file():  # restored from its published files: no generations
        with (root / "metrics.csv").open() as f:
            rows = list(csv.DictReader(f))
    else:
        rows = RunDir(root).metrics_rows()
    if not rows:
        return {}
    last = rows[-1]

    def number(row, key):
        value = row.get(key, "")
        return float(value) if value not in ("", None) else 0.0

    departed = phi_departure(rows)
    # generation 0 (a population's build or adoption) has a row only where there is one
    zero = rows[0] if int(number(rows[0], "generation")) == 0 else None
    return {
        **({} if departed is None else {"phi_tv_max": round(departed, 6)}),
        "env_steps": int(number(last, "env_steps")),
        "learner_samples": int(number(last, "learner_samples")),
        "gradient_steps": int(number(last, "gradient_steps")),
        "pretrain_env_steps": int(number(rows[0], "pretrain_env_steps")),
        "train_s": round(float(last["cumulative_wall_s"]), 1),
        "learner_train_s": round(
            float(last["cumulative_wall_s"]) - (float(zero["cumulative_wall_s"]) if zero else 0.0),
            1,
        ),
    }


def trial_entry(
    trial: str, pools: Mapping[str, Mapping[str, Any]], spent: Mapping[str, Any]
) -> dict[str, Any]:
    """One trial's line of results.json: its method and seed, what its training took and
    its figures against each pool (the learner's scale without its per-episode rows)."""
    from hola_ray.evaluation.compare import METRICS

    method, seed = parse_trial(trial)
    return {
        "method": method,
        "seed": seed,
        **spent,
        "pools": {
            p: {k: r[k] for k in METRICS}
            | {f"{k}_se": r[f"{k}_se"] for k in METRICS}
            | {"score": r["score_iqm"]}
            | (
                {"scale": {k: v for k, v in r["scale"].items() if k != "per_episode"}}
                if "scale" in r
                else {}
            )
            for p, r in pools.items()
        },
    }


def write_results(
    exp: Experiment,
    out: Path,
    per_trial: Mapping[str, Mapping[str, Any]],
    spent: Mapping[str, Mapping[str, Any]],
    builds: Mapping[str, str],
    stopped_short: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """results.json, results.md and figure.png in `out` from every trial's evaluation
    (`per_trial`), what its training took (`spent`, `budget_spent`) and the label of the
    population it was built on (`builds`); returns what results.json holds. An experiment
    ended before its plan (`--stop-short`) says so: `stopped_short` names the seeds
    evaluated and the trials left out."""
    methods, differences = aggregate(per_trial, list(exp.methods), exp.pairs())
    checked = builds_check(
        {t: {p: r["success"] for p, r in pools_.items()} for t, pools_ in per_trial.items()},
        exp.pairs(),
        dict(builds),
    )
    trials = {t: trial_entry(t, pools_, spent[t]) for t, pools_ in per_trial.items()}
    results = {
        "experiment": str(exp.source) if exp.source else None,
        "base": exp.base,
        "seeds": list(exp.seeds),
        **({"stopped_short": dict(stopped_short)} if stopped_short else {}),
        "evaluation": {
            "episodes_per_seed": exp.evaluation.episodes,
            "seeds": list(exp.evaluation.seeds),
            "learner": exp.evaluation.learner,
        },
        "trials": trials,
        "methods": methods,
        "differences": differences,
        "builds": checked,
        "verdict": verdict_sentence(differences, exp.pairs()[0][0]) if exp.pairs() else {},
        "intervals": INTERVALS,
    }
    _atomic_json(out / "results.json", results)
    write_tables(exp, out, results)
    return results


def write_tables(exp: Experiment, out: Path, results: Mapping[str, Any]) -> None:
    """figure.png and results.md from results.json's figures: the verdict, the table of
    methods and differences, the builds' check, and the trials whose φ drew partners as
    the rival rule's did."""
    from hola_ray.evaluation.report import plot
    from hola_ray.population.rundir import PHI_TIE

    figure_input = {
        m: {p: {**r, "score_iqm": r["score"]} for p, r in pools_.items()}
        for m, pools_ in results["methods"].items()
    }
    png, _ = plot(figure_input, out)
    png.replace(out / "figure.png")
    (out / "evaluation.md").unlink(missing_ok=True)
    trials = results["trials"]
    same = sorted(t for t, x in trials.items() if x.get("phi_tv_max", 1.0) <= PHI_TIE)
    note = (
        f"\nφ never departed from the rival rule's by more than {PHI_TIE} (total "
        f"variation, every generation) in: {', '.join(same)}; there the two rules drew "
        "partners alike.\n"
        if same
        else ""
    )
    said = results["verdict"].get("sentence")
    short = results.get("stopped_short")
    seeds = len(short["seeds"]) if short else len(exp.seeds)
    (out / "results.md").write_text(
        (
            f"**Stopped short of the plan**: {seeds} of {len(exp.seeds)} seeds evaluated "
            f"(those whose every method finished); left out: {', '.join(short['left_out'])}."
            "\n\n"
            if short
            else ""
        )
        + (f"**Verdict** (the rule fixed before the runs): {said}\n\n" if said else "")
        + results_table(figure_input, results["differences"], seeds)
        + builds_table(results["builds"])
        + note
    )
