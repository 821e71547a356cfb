"""The experiment's results: per method and pool over the trials, the paired differences
between methods (`hola_ray.evaluation.compare`), and results.md's table."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.experiment.config import parse_trial

DETECTABLE = 1.96 + 0.84
"""the smallest true difference found 80 % of the time by a two-sided 5 % test, in standard
errors of the measured difference (z at 0.975 plus z at 0.8)"""

EVALUATION_FORMAT = 2
"""the layout of a cached trial evaluation (2: every episode's record, for the bootstrap)"""


def aggregate(
    per_trial: Mapping[str, Mapping[str, Mapping[str, Any]]],
    methods: Sequence[str],
    pairs: Sequence[tuple[str, str]] = (),
) -> tuple[dict[str, dict[str, dict[str, Any]]], dict[str, dict[str, dict[str, Any]]]]:
    """Per method and pool: every metric's mean over the method's seeds with its standard
    error (`_se`) and 95 % interval (`_ci95`), and the BR-Prox score's mean over seeds; per
    pair "A-B" and pool, each metric's paired difference {mean, se, ci95}. Intervals and
    standard errors from `hola_ray.evaluation.compare` (training seeds and episodes)."""
    from hola_ray.evaluation.compare import METRICS, compare
    from hola_ray.evaluation.scale import FLOOR

    pools_ = sorted({p for r in per_trial.values() for p in r}, key=lambda p: (p != "hot", p))
    out: dict[str, dict[str, dict[str, Any]]] = {m: {} for m in methods}
    differences: dict[str, dict[str, dict[str, Any]]] = {f"{a}-{b}": {} for a, b in pairs}
    for pool in pools_:
        seeded: dict[str, list[tuple[int, Any]]] = {m: [] for m in methods}
        for t, r in per_trial.items():
            m, seed = parse_trial(t)
            if m in seeded and pool in r:
                seeded[m].append((seed, r[pool]))
        for found in seeded.values():
            found.sort(key=lambda x: x[0])  # seed order: seed s of two methods is a pair
        rows = {m: [row for _, row in found] for m, found in seeded.items() if found}
        episodes = {
            m: [{k: np.asarray(v) for k, v in r["per_episode"].items()} for r in rs]
            for m, rs in rows.items()
        }
        wanted = [(a, b) for a, b in pairs if a in rows and b in rows]
        seeds = {m: [seed for seed, _ in seeded[m]] for m in rows}
        # the reference seats played the same episodes for every trial: any trial's record
        seats = next((r["scale"] for rs in rows.values() for r in rs if "scale" in r), None)
        scale = None
        if seats is not None:
            refs = {
                f"@{k}": [{f: np.asarray(v) for f, v in e.items()}]
                for k, e in seats["per_episode"].items()
            }
            episodes = {**episodes, **refs}
            scale = (f"@{FLOOR}", [f"@{c}" for c in seats["ceilings"]])
        figures, diffs = compare(episodes, wanted, seeds=seeds, scale=scale)
        for m, rs in rows.items():
            entry: dict[str, Any] = {"trials": len(rs)}
            for k in METRICS:
                entry[k] = figures[m][k]["mean"]
                entry[f"{k}_se"] = figures[m][k]["se"]
                entry[f"{k}_ci95"] = figures[m][k]["ci95"]
            scores = np.array([r["score_iqm"] for r in rs], dtype=np.float64)
            entry["score"] = float(scores.mean())
            entry["score_se"] = (
                float(scores.std(ddof=1) / np.sqrt(scores.size)) if scores.size > 1 else 0.0
            )
            if seats is not None:
                entry["scale"] = {
                    "floor": seats["floor"],
                    "ceilings": seats["ceilings"],
                    "normalised": {c.lstrip("@"): v for c, v in figures[m]["normalised"].items()},
                }
            out[m][pool] = entry
        for (a, b), key in zip(wanted, diffs, strict=True):
            differences[f"{a}-{b}"][pool] = diffs[key]
    return out, differences


def results_table(
    methods: Mapping[str, Mapping[str, Mapping[str, Any]]],
    differences: Mapping[str, Mapping[str, Mapping[str, Any]]],
    seeds: int,
) -> str:
    """results.md: every method's figures, then the paired differences with a verdict."""
    from hola_ray.evaluation.compare import HIGHER_IS_BETTER, verdict
    from hola_ray.evaluation.report import table_lines

    lines = [
        f"Mean over {seeds} training seed(s) per method; [95 % interval]: a stratified "
        "bootstrap over training seeds (within each method) and evaluation episodes (within "
        "each partner combination). Steps to success: mean length of the successful "
        "episodes (AT-Drone's AST); reward: mean per-pursuer return (REW).",
        "",
        *table_lines(methods, "method"),
        "",
        "Paired differences A − B on the same episodes (and, where the two methods share "
        "their training seeds, resampled seed by seed), [95 % interval]. An interval that "
        "contains zero is a tie. Detectable: the smallest success difference this design "
        "finds 4 times in 5 at the 5 % level, 2.8 × the difference's standard error.",
        "",
        "| A − B | pool | success | detectable | collision | length | learner crashed |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for pair, by_pool in differences.items():
        a = pair.split("-")[0]
        for pool, diff in by_pool.items():
            cells = []
            for m in ("success", "collision", "length", "learner_crash"):
                d = diff[m]
                lo, hi = d["ci95"]
                word = verdict(d, HIGHER_IS_BETTER[m])
                word = "tie" if word == "tie" else f"{a} {word}"
                if m == "length":
                    cells.append(f"{d['mean']:+.1f} [{lo:+.1f}, {hi:+.1f}] {word}")
                else:
                    cells.append(f"{d['mean']:+.1%} [{lo:+.1%}, {hi:+.1%}] {word}")
                if m == "success":
                    cells.append(f"{DETECTABLE * d['se']:.1%}")
            lines.append(f"| {pair} | {pool} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


GOAL_WIDTH = 0.12
"""the comparison's design goal: a hola − X success interval with HeT that is not above zero is at
most 12 points wide"""


def verdict_sentence(
    differences: Mapping[str, Mapping[str, Mapping[str, Any]]],
    method: str,
    pool: str = "het",
    metric: str = "success",
) -> dict[str, Any]:
    """The verdict fixed before the experiment (results/NOTEBOOK.md, "The analysis"), in
    one sentence: `method` − X on `metric` with `pool` is ahead (or behind) where its 95 %
    interval excludes 0, else a tie, for every X it is paired with; beside it the smallest
    difference the design detects and whether every interval not above zero is at most
    `GOAL_WIDTH` wide. None of it depends on which way the figures fall."""
    from hola_ray.evaluation.compare import HIGHER_IS_BETTER, verdict
    from hola_ray.evaluation.report import POOL_LABELS

    named: dict[str, dict[str, str]] = {"ahead": {}, "behind": {}, "tie": {}}  # X → its figures
    detect, widths = [], []
    for pair, by_pool in differences.items():
        a, b = pair.split("-", 1)
        if a != method or metric not in by_pool.get(pool, {}):
            continue
        d = by_pool[pool][metric]
        lo, hi = d["ci95"]
        word = verdict(d, HIGHER_IS_BETTER[metric])
        named[word][b] = f"{d['mean'] * 100:+.1f} [{lo * 100:+.1f}, {hi * 100:+.1f}]"
        detect.append(DETECTABLE * d["se"])
        if not lo > 0:
            widths.append(hi - lo)
    if not detect:
        return {}
    parts = [
        lead + ", ".join(f"{x} ({figures})" for x, figures in named[word].items())
        for word, lead in (("ahead", "ahead of "), ("behind", "behind "), ("tie", "tied with "))
        if named[word]
    ]
    widest = max(widths, default=0.0)
    met = round(widest * 100, 1) <= GOAL_WIDTH * 100  # as written, to a tenth of a point
    low, high = (f"{x * 100:.1f}" for x in (min(detect), max(detect)))
    sentence = (
        f"With {POOL_LABELS.get(pool, pool)} teammates, {method}'s {metric} is "
        + "; ".join(parts)
        + f" ({method} − X in points [95 %]); the design detects "
        + (low if low == high else f"{low}–{high}")
        + " points at 80 % power, and "
        + (
            f"every interval not above zero is at most {widest * 100:.1f} points wide"
            if met
            else f"the widest interval not above zero is {widest * 100:.1f} points, "
            f"wider than the {GOAL_WIDTH * 100:.0f} the design aimed at"
        )
        + "."
    )
    return {
        "sentence": sentence,
        "pool": pool,
        "metric": metric,
        **{word: list(xs) for word, xs in named.items()},
        "detectable": [float(min(detect)), float(max(detect))],
        "widest_not_ahead": float(widest),
        "design_met": bool(met),
    }


def build_label(population: str, seed: int) -> str | None:
    """The population build a trial of `seed` trains beside, kind aside: the
    `pretrain.population` template with its seed filled in (`{kind}-3v2-s{seed%3}` at seed 4
    reads `{kind}-3v2-s1`, the same build index for hola's MEP and fcp's FCP population);
    None for a method with no population (`none`)."""
    if population in ("", "none", None):
        return None
    text = str(population).replace("{seed}", str(seed))
    return re.sub(r"\{seed%(\d+)\}", lambda m: str(seed % int(m[1])), text)


def builds_check(
    success: Mapping[str, Mapping[str, float]],
    pairs: Sequence[tuple[str, str]],
    build_of: Mapping[str, str | None],
) -> dict[str, dict[str, dict[str, Any]]]:
    """The population builds as the unit, a check beside the seeds' bootstrap (which takes
    the seeds as independent, while seeds of one build share it). Per pair "A-B" and pool:
    the paired success differences of the seeds both methods ran, grouped by the build
    their seed trains beside (`build_of[trial]`, A's and B's together); each build's mean;
    the mean of the build means with a t-interval on k − 1 degrees of freedom (k builds,
    each one observation: every source of noise below a build is inside its mean); and a
    one-way analysis of variance, F = between-build over within-build mean square with its
    p-value: a small p says the builds differ beyond what the seeds' spread explains, and
    then the builds' interval, not the seeds', is the honest one. Pairs whose seeds fall in
    fewer than two builds, or one seed a build, are left out. `success[trial][pool]`: the
    trial's mean success."""
    from scipy import stats

    seeds_of: dict[str, set[int]] = {}
    for t in success:
        method, seed = parse_trial(t)
        seeds_of.setdefault(method, set()).add(seed)
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for a, b in pairs:
        seeds = seeds_of.get(a, set()) & seeds_of.get(b, set())
        for pool in sorted({p for t in success for p in success[t]}):
            groups: dict[str, list[float]] = {}
            for s in sorted(seeds):
                ta, tb = f"{a}-s{s}", f"{b}-s{s}"
                if pool not in success[ta] or pool not in success[tb]:
                    continue
                labels = [x for x in (build_of.get(ta), build_of.get(tb)) if x is not None]
                if not labels:
                    continue
                label = " & ".join(dict.fromkeys(labels))
                groups.setdefault(label, []).append(success[ta][pool] - success[tb][pool])
            k = len(groups)
            n = sum(len(g) for g in groups.values())
            if k < 2 or n == k:
                continue
            means = np.array([np.mean(g) for g in groups.values()])
            sizes = np.array([len(g) for g in groups.values()])
            grand = float(means.mean())
            se = float(means.std(ddof=1) / np.sqrt(k))
            half = float(stats.t.ppf(0.975, k - 1)) * se
            overall = float((sizes * means).sum() / n)
            between = float((sizes * (means - overall) ** 2).sum()) / (k - 1)
            within = sum(
                float(((np.asarray(g) - m) ** 2).sum())
                for g, m in zip(groups.values(), means, strict=True)
            )
            within /= n - k
            # seeds alike within every build: any spread between builds is theirs alone
            f_stat = float(between / within) if within > 0 else (1e9 if between > 0 else 0.0)
            out.setdefault(f"{a}-{b}", {})[pool] = {
                "builds": {
                    label: {"seeds": len(g), "mean": float(m)}
                    for (label, g), m in zip(groups.items(), means, strict=True)
                },
                "mean": grand,
                "se": se,
                "ci95": [grand - half, grand + half],
                "F": f_stat,
                "p": float(stats.f.sf(f_stat, k - 1, n - k)),
            }
    return out


def builds_table(check: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str:
    """results.md's section on `builds_check`."""
    if not check:
        return ""
    lines = [
        "",
        "The population builds as the unit (a check beside the seeds' bootstrap above, "
        "which takes seeds of one build as independent): each build's mean paired success "
        "difference, the mean of the build means with a t-interval over builds [95 %], and "
        "the F test of whether builds differ beyond the seeds' spread (a small p: trust the "
        "builds' interval).",
        "",
        "| A − B | pool | per build | over builds | F (p) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for pair, by_pool in check.items():
        for pool, c in by_pool.items():
            per = ", ".join(
                f"{label} {x['mean']:+.1%} (n {x['seeds']})" for label, x in c["builds"].items()
            )
            lo, hi = c["ci95"]
            lines.append(
                f"| {pair} | {pool} | {per} | {c['mean']:+.1%} [{lo:+.1%}, {hi:+.1%}] "
                f"| {c['F']:.2f} ({c['p']:.2f}) |"
            )
    return "\n".join(lines) + "\n"


def _atomic_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)
