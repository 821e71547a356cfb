"""A comparison's plan, fixed before its first trial, and the one analysis it names.

    python -m hola_ray.experiment.plan PLAN.yaml DIR [--out FOLDER]

`PLAN.yaml` names the experiment file, the method every baseline is compared with, the
baselines (Holm's family), the primary figure (a pool and a metric of `results.json`), the
builds and the seeds of each, the margin tested, the familywise α, the widest interval a tie
may have, and the checks: learners' competence, levelled validation curves, φ departing
from the ablation's. `DIR` is the experiment's output or its published copy
(`results.json` and `trials/*/metrics.csv`). It writes `plan.json` and `plan.md` beside
them (or in `--out`). The rule, in docs/plan.md:

- **The unit is the build.** A trial of seed s belongs to build s mod `builds` (its
  population `…-s{seed%builds}`; a method without a population is grouped the same way,
  so each build holds the same seeds for every method). A build counts once all its seeds
  of both methods of a pair are in; the figure of a build is the mean over its seeds, so
  every source of noise below a build (seeds, episodes) is inside it.
- **Per baseline X**: d_b = reference_b − X_b over the B builds; a t statistic on B − 1
  degrees of freedom; p for "reference > X" and for "reference ≥ X + margin" (one-sided),
  and the two-sided p for "they differ", which orders Holm's steps.
- **Holm's intervals**: with the two-sided p-values ordered, step i (of k) is tested at
  α / (k − i + 1); the interval of step i is the two-sided t interval at that level, and
  every step after the first that fails keeps the failing step's level (so no interval
  after it excludes 0 on its own). Holm-adjusted p-values are given for both one-sided
  families.
- **Verdict** from the interval [lo, hi]: ahead (lo > 0; "by the margin" when lo > margin),
  behind (hi < 0), a tie (0 inside and hi − lo ≤ `tie_width`), else inconclusive.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.config.reader import ConfigError, load_yaml
from hola_ray.experiment.config import parse_trial


@dataclass(frozen=True)
class Plan:
    """A comparison's plan (module doc); every field is required in the file."""

    experiment: str
    """the experiment file, repository-relative"""
    reference: str
    """the method every baseline is compared with"""
    baselines: tuple[str, ...]
    """Holm's family"""
    pool: str
    """the primary figure's pool"""
    figure: str
    """the primary figure's metric in results.json (a rate: success, collision, …)"""
    builds: int
    seeds_per_build: int
    margin: float
    """the paper's margin, tested as "reference ≥ X + margin" """
    alpha: float
    """familywise error rate over the baselines"""
    tie_width: float
    """the widest Holm-adjusted interval a tie may have"""
    level_generations: int
    """the late generations whose validation slope must hold 0 in its interval"""
    competence_each: float
    """every reference learner's primary figure at least this"""
    competence_median: float
    """their median at least this"""
    phi_departure: float
    """every reference trial's largest phi_tv (its φ against its ablation's) at least this"""

    @classmethod
    def from_yaml(cls, path: str | Path) -> Plan:
        raw = load_yaml(path)
        fields = cls.__dataclass_fields__
        if not isinstance(raw, Mapping) or set(raw) != set(fields):
            have = set(raw) if isinstance(raw, Mapping) else set()
            raise ConfigError(
                f"{path}: a plan names exactly {', '.join(fields)}; missing "
                f"{sorted(set(fields) - have)}, unknown {sorted(have - set(fields))}"
            )
        plan = cls(**{**raw, "baselines": tuple(raw["baselines"])})
        if plan.builds < 2 or plan.seeds_per_build < 1 or not 0 < plan.alpha < 1:
            raise ConfigError(f"{path}: builds ≥ 2, seeds_per_build ≥ 1 and 0 < alpha < 1")
        return plan

    def check_seeds(self, seeds: Sequence[int]) -> None:
        """The experiment's seeds give every build `seeds_per_build` seeds, or one error."""
        counts = np.bincount(np.asarray(seeds) % self.builds, minlength=self.builds)
        if len(seeds) != len(set(seeds)) or set(counts.tolist()) != {self.seeds_per_build}:
            raise ConfigError(
                f"the experiment's seeds give the builds {counts.tolist()} seeds, not "
                f"{self.seeds_per_build} each"
            )


# ---- the builds ---------------------------------------------------------------------------
def build_means(
    figures: Mapping[str, float], method: str, plan: Plan, seeds: Sequence[int]
) -> dict[int, float]:
    """Build → the mean of `method`'s figure over the build's seeds, for the builds whose
    every seed is in `figures` (trial name → figure)."""
    out = {}
    for b in range(plan.builds):
        mine = [s for s in seeds if s % plan.builds == b]
        values = [figures.get(f"{method}-s{s}") for s in mine]
        if mine and all(v is not None for v in values):
            out[b] = float(np.mean(values))
    return out


def t_test(d: np.ndarray, margin: float) -> dict[str, float]:
    """The builds' differences: mean, standard error, and p for "> 0", "> margin" and
    "≠ 0" on len(d) − 1 degrees of freedom."""
    from scipy import stats

    k = d.size
    mean = float(d.mean())
    se = float(d.std(ddof=1) / math.sqrt(k))
    df = k - 1
    if se == 0.0:  # every build the same: the sign decides
        big = math.copysign(math.inf, mean) if mean else 0.0
        t0 = big
        tm = math.copysign(math.inf, mean - margin) if mean != margin else 0.0
    else:
        t0, tm = mean / se, (mean - margin) / se
    return {
        "builds": k,
        "mean": mean,
        "se": se,
        "sd": float(d.std(ddof=1)),
        "p_ahead": float(stats.t.sf(t0, df)),
        "p_margin": float(stats.t.sf(tm, df)),
        "p_differ": float(min(1.0, 2 * stats.t.sf(abs(t0), df))),
    }


def holm(p: Mapping[str, float], alpha: float) -> dict[str, dict[str, float]]:
    """Holm's step-down over `p` (name → p): per name its step, the two-sided level its
    interval takes (module doc), whether it is rejected, and its adjusted p."""
    order = sorted(p, key=lambda n: (p[n], n))
    k = len(order)
    out: dict[str, dict[str, float]] = {}
    failed_at: int | None = None
    running = 0.0
    for i, name in enumerate(order):
        step = i if failed_at is None else failed_at
        a = alpha / (k - step)
        rejected = failed_at is None and p[name] <= a
        if failed_at is None and not rejected:
            failed_at = i
        running = max(running, min(1.0, (k - i) * p[name]))
        out[name] = {"step": i + 1, "alpha": a, "rejected": rejected, "p_adjusted": running}
    return out


def holm_adjusted(p: Mapping[str, float]) -> dict[str, float]:
    """Holm-adjusted p-values of one family."""
    order = sorted(p, key=lambda n: (p[n], n))
    out, running = {}, 0.0
    for i, name in enumerate(order):
        running = max(running, min(1.0, (len(order) - i) * p[name]))
        out[name] = running
    return out


def verdict(lo: float, hi: float, margin: float, tie_width: float) -> str:
    """The fixed rule's word for an interval of reference − baseline."""
    if lo > margin:
        return "ahead by the margin"
    if lo > 0:
        return "ahead"
    if hi < 0:
        return "behind"
    if hi - lo <= tie_width:
        return "tie"
    return "inconclusive"


def compare_builds(
    figures: Mapping[str, float], plan: Plan, seeds: Sequence[int]
) -> dict[str, dict[str, Any]]:
    """Per baseline: the builds' differences, the tests, Holm's level and interval, and the
    verdict (module doc). Baselines with fewer than two complete builds are left out."""
    from scipy import stats

    ref = build_means(figures, plan.reference, plan, seeds)
    tests: dict[str, dict[str, Any]] = {}
    for x in plan.baselines:
        other = build_means(figures, x, plan, seeds)
        common = sorted(set(ref) & set(other))
        if len(common) < 2:
            continue
        d = np.array([ref[b] - other[b] for b in common])
        tests[x] = t_test(d, plan.margin) | {
            "per_build": dict(zip(common, d.tolist(), strict=True))
        }
    if not tests:
        return {}
    steps = holm({x: t["p_differ"] for x, t in tests.items()}, plan.alpha)
    ahead = holm_adjusted({x: t["p_ahead"] for x, t in tests.items()})
    margin = holm_adjusted({x: t["p_margin"] for x, t in tests.items()})
    for x, t in tests.items():
        level = 1 - steps[x]["alpha"]
        half = float(stats.t.ppf(1 - steps[x]["alpha"] / 2, t["builds"] - 1)) * t["se"]
        lo, hi = t["mean"] - half, t["mean"] + half
        t |= {
            "holm_step": steps[x]["step"],
            "level": level,
            "interval": [lo, hi],
            "width": hi - lo,
            "p_ahead_holm": ahead[x],
            "p_margin_holm": margin[x],
            "verdict": verdict(lo, hi, plan.margin, plan.tie_width),
        }
    return tests


# ---- the checks ---------------------------------------------------------------------------
def read_metrics(folder: Path) -> dict[str, list[dict[str, str]]]:
    """Trial name → its metrics.csv rows, for every trial folder under `folder/trials`."""
    out = {}
    for path in sorted((folder / "trials").glob("*/metrics.csv")):
        with path.open() as f:
            out[path.parent.name] = list(csv.DictReader(f))
    return out


def late_slope(rows: Sequence[Mapping[str, str]], generations: int) -> float | None:
    """The least-squares slope of val_success per generation over the last `generations`
    generations that have it; None with fewer."""
    points = [(int(r["generation"]), float(r["val_success"])) for r in rows if r.get("val_success")]
    if len(points) < max(generations, 2):
        return None
    g, v = np.array(points[-generations:]).T
    return round(float(np.polyfit(g, v, 1)[0]), 12)  # a flat curve's rounding is no rise


def levelled(
    metrics: Mapping[str, Sequence[Mapping[str, str]]],
    plan: Plan,
    seeds: Sequence[int],
    methods: Sequence[str],
) -> dict[str, dict[str, Any]]:
    """Per method: the late validation slope's build means, their mean with a 95 % t
    interval over builds, and whether the curve has levelled (the interval's low end ≤ 0)."""
    from scipy import stats

    out = {}
    for m in methods:
        slopes = {t: late_slope(rows, plan.level_generations) for t, rows in metrics.items()}
        means = build_means({t: s for t, s in slopes.items() if s is not None}, m, plan, seeds)
        if len(means) < 2:
            continue
        v = np.array(list(means.values()))
        half = float(stats.t.ppf(0.975, v.size - 1)) * float(v.std(ddof=1) / math.sqrt(v.size))
        lo, hi = float(v.mean()) - half, float(v.mean()) + half
        out[m] = {
            "builds": v.size,
            "slope": float(v.mean()),
            "interval": [lo, hi],
            "levelled": lo <= 0,
        }
    return out


def joins(rows: Sequence[Mapping[str, str]]) -> dict[str, Any]:
    """A trial's joins (generations whose candidate joined) with their η, and its largest
    phi_tv and phi_tv_uniform."""

    def largest(key: str) -> float:
        values = [float(r[key]) for r in rows if r.get(key)]
        return max(values) if values else 0.0

    joined = [r for r in rows if r.get("accepted") == "1"]
    return {
        "joins": len(joined),
        "eta": [round(float(r["eta"]), 3) for r in joined],
        "generations": sum(1 for r in rows if r.get("accepted") not in (None, "")),
        "phi_tv_max": largest("phi_tv"),
        "phi_tv_uniform_max": largest("phi_tv_uniform"),
    }


def competence(figures: Mapping[str, float], plan: Plan) -> dict[str, Any]:
    """The reference learners' primary figures against the plan's competence level."""
    mine = {t: v for t, v in figures.items() if parse_trial(t)[0] == plan.reference}
    values = np.array(list(mine.values())) if mine else np.array([np.nan])
    below = sorted(t for t, v in mine.items() if v < plan.competence_each)
    median = float(np.median(values))
    return {
        "learners": len(mine),
        "median": median,
        "lowest": float(values.min()),
        "below": below,
        "met": bool(mine) and not below and median >= plan.competence_median,
    }


# ---- the analysis -------------------------------------------------------------------------
def analyse(plan: Plan, folder: Path, seeds: Sequence[int]) -> dict[str, Any]:
    """Every figure the plan names, from `folder`'s results.json and trials' metrics."""
    results = json.loads((folder / "results.json").read_text())
    figures = {
        t: r["pools"][plan.pool][plan.figure]
        for t, r in results["trials"].items()
        if plan.pool in r.get("pools", {})
    }
    methods = [plan.reference, *plan.baselines]
    metrics = read_metrics(folder)
    complete = {m: len(build_means(figures, m, plan, seeds)) for m in methods}
    scale = {}
    for m in methods:
        entry = results.get("methods", {}).get(m, {}).get(plan.pool, {})
        if "scale" in entry:
            s = entry["scale"]
            scale[m] = {
                "figure": entry[plan.figure],
                "floor": s["floor"][plan.figure],
                "ceilings": {c: v[plan.figure] for c, v in s["ceilings"].items()},
                "normalised": {c: v["mean"] for c, v in s["normalised"].items()},
            }
    reference_trials = sorted(t for t in metrics if parse_trial(t)[0] == plan.reference)
    phi = {t: joins(metrics[t]) for t in reference_trials}
    return {
        "plan": dict(plan.__dict__, baselines=list(plan.baselines)),
        "builds_complete": complete,
        "stopped_short": any(n < plan.builds for n in complete.values()),
        "comparisons": compare_builds(figures, plan, seeds),
        "competence": competence(figures, plan),
        "levelled": levelled(metrics, plan, seeds, methods),
        "phi": phi,
        "phi_departs_everywhere": bool(phi)
        and all(p["phi_tv_max"] >= plan.phi_departure for p in phi.values()),
        "scale": scale,
    }


def _pct(x: float) -> str:
    return f"{100 * x:+.1f}"


def plan_table(a: Mapping[str, Any]) -> str:
    """plan.md: the verdicts first, then what bounds them."""
    p = a["plan"]
    lines = [
        f"# {p['reference']} against each baseline, builds as the unit",
        "",
        f"Primary figure: {p['figure']} with {p['pool']}; per baseline the mean over builds of "
        f"({p['reference']} − baseline), points, with Holm's interval (familywise α {p['alpha']}); "
        f"margin {100 * p['margin']:.0f} points; a tie is an interval holding 0 no wider than "
        f"{100 * p['tie_width']:.0f} points.",
        "",
    ]
    if a["stopped_short"]:
        done = ", ".join(f"{m} {n}" for m, n in a["builds_complete"].items())
        lines += [f"**Stopped short of the plan**: complete builds of {p['builds']}: {done}.", ""]
    lines += [
        "| baseline | builds | difference | Holm interval (level) | width "
        "| p (> 0), Holm | p (≥ +margin), Holm | verdict |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for x, c in sorted(a["comparisons"].items(), key=lambda kv: kv[1]["holm_step"]):
        lo, hi = c["interval"]
        lines.append(
            f"| {x} | {c['builds']} | {_pct(c['mean'])} | [{_pct(lo)}, {_pct(hi)}] "
            f"({100 * c['level']:.2f} %) | {100 * c['width']:.1f} | {c['p_ahead_holm']:.3f} "
            f"| {c['p_margin_holm']:.3f} | **{c['verdict']}** |"
        )
    comp = a["competence"]
    lines += [
        "",
        f"Competence ({p['reference']}'s {p['figure']} with {p['pool']}): {comp['learners']} "
        f"learners, median {100 * comp['median']:.1f} % "
        f"(plan: ≥ {100 * p['competence_median']:.1f}), "
        f"lowest {100 * comp['lowest']:.1f} % (plan: each ≥ {100 * p['competence_each']:.1f}); "
        f"{'met' if comp['met'] else 'not met'}"
        + (f"; below: {', '.join(comp['below'])}" if comp["below"] else "")
        + ".",
        "",
        f"Levelled validation curves (slope of val_success per generation over the last "
        f"{p['level_generations']}, mean over builds [95 %]):",
        "",
        "| method | builds | slope (points per generation) | levelled |",
        "| --- | --- | --- | --- |",
    ]
    for m, lv in a["levelled"].items():
        lo, hi = lv["interval"]
        lines.append(
            f"| {m} | {lv['builds']} | {100 * lv['slope']:+.2f} [{100 * lo:+.2f}, {100 * hi:+.2f}] "
            f"| {'yes' if lv['levelled'] else 'no: still rising'} |"
        )
    phi = a["phi"]
    lines += [
        "",
        f"φ against the ablation's: every {p['reference']} trial's largest phi_tv ≥ "
        f"{p['phi_departure']}: {'yes' if a['phi_departs_everywhere'] else 'no'}; joins per "
        f"trial {[v['joins'] for v in phi.values()]}, their η all > 0: "
        f"{all(e > 0 for v in phi.values() for e in v['eta'])}.",
    ]
    if a["scale"]:
        lines += [
            "",
            "The learner's scale (same episodes): floor, ceilings and each method's "
            "normalised score.",
            "",
            "| method | figure | floor | ceilings | normalised |",
            "| --- | --- | --- | --- | --- |",
        ]
        for m, s in a["scale"].items():
            ceil = ", ".join(f"{c} {100 * v:.1f}" for c, v in s["ceilings"].items())
            norm = ", ".join(f"{c} {v:.2f}" for c, v in s["normalised"].items())
            lines.append(
                f"| {m} | {100 * s['figure']:.1f} | {100 * s['floor']:.1f} | {ceil} | {norm} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    from hola_ray.experiment.config import Experiment
    from hola_ray.homes import ROOT

    parser = argparse.ArgumentParser(
        prog="python -m hola_ray.experiment.plan", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("plan", type=Path)
    parser.add_argument("folder", type=Path, help="the experiment's output or its published copy")
    parser.add_argument("--out", type=Path, default=None, help="default: the folder")
    args = parser.parse_args(argv)
    plan = Plan.from_yaml(args.plan)
    seeds = Experiment.from_yaml(ROOT / plan.experiment).seeds
    plan.check_seeds(seeds)
    analysis = analyse(plan, args.folder, seeds)
    out = args.out or args.folder
    out.mkdir(parents=True, exist_ok=True)
    (out / "plan.json").write_text(json.dumps(analysis, indent=1) + "\n")
    (out / "plan.md").write_text(plan_table(analysis))
    print(plan_table(analysis))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
