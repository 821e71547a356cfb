"""Zero-shot evaluation against unseen teammate pools (paper §V, Fig. 4; SPEC §5).

    python -m hola_ray.evaluate RUN_DIR|POLICY.pt [...] [--pool hot|het|DIR ...]
        [--partner MODULE:CALLABLE ...] [--episodes 50] [--seeds 0 1 2]
        [--plot] [--out DIR] [--json]

Per learner and pool, `--episodes` episodes per seed: the learner sits in a random seat
and its n_p − 1 teammates are drawn from the pool, uniformly with replacement, per episode.
Success, collision and length are averaged per seed; the figures are their mean over
seeds, the standard error over seeds and a 95 % bootstrap interval over seeds.

The normalised score follows ZSC-Eval's BR-Prox: for every combination of pool members in
the other seats and every seat, R(ref) is the best mean team return that any pool member
reaches in that seat with those teammates, and the learner's cell scores
min(1, max(R(learner), 0) / R(ref)); cells where no pool member reaches a positive return
(R(ref) ≤ 0) have no reference and are left out (their count is reported). `score_iqm` is
the interquartile mean over combinations × seats × seeds. Each cell plays the same
`--cell-episodes` episode seeds for the learner and every pool member.

The scenario is the arena's default (Table I) with the learners' number of evaders (the
paper's evaluation is 3 vs 2; every learner given must share it) and the arena's default
rewards (the team return that the score compares; a run's own reward shaping is not used).
Pool members trained for more evaders play fewer through `ScenarioAdapter`.

A learner is a run directory (its final `learner.pt`) or an exported policy file.
`--partner MODULE:CALLABLE` (repeatable; MODULE a module name or a path to a .py file)
adds a teammate of your own: the callable gets the `PursuitConfig` and returns an object
with `act(obs) → actions` and `reset(mask)`; the partners form a pool named `partners`.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import itertools
import json
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.env.config import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.registry import load_export, load_policy, policy_file
from hola_ray.pools import POOLS, PoolError, load_pool

METRICS = ("success", "collision", "length")
CRASHES = ("learner_crash", "teammate_crash")
"""whose collisions: the share of episodes in which the learner's own seat collided, and
the share of teammate seats that collided (`collision` counts an episode with any)"""


class EvaluationError(RuntimeError):
    """A command line that cannot be evaluated: one clear message."""


# ---- who plays ------------------------------------------------------------------------------
def learner_evaders(path: Path, config: PursuitConfig) -> int:
    """How many evaders a learner was trained against (its run's config, or the export's
    input size): the evaluation plays that scenario."""
    path = Path(path)
    if path.is_dir() and (path / "config.yaml").is_file():
        import yaml

        env = (yaml.safe_load((path / "config.yaml").read_text()) or {}).get("env") or {}
        return int(env.get("n_evaders", config.n_evaders))
    file = policy_file(path)
    try:
        export = load_export(path)
    except ValueError as err:
        raise EvaluationError(str(err)) from err
    if export.get("scenario"):
        return int(export["scenario"].get("n_evaders", config.n_evaders))
    inputs = export["weights"][0].shape[1] - len((export.get("features") or {}).get("indices", ()))
    rest = 2 + 2 * (config.n_pursuers - 1) + 4  # obstacle, teammates, own
    if (inputs - rest) % 3 or inputs <= rest:
        raise EvaluationError(f"{file}: an input of {inputs} fits no number of evaders")
    return (inputs - rest) // 3


def load_learner(path: Path, config: PursuitConfig) -> tuple[str, Any]:
    """(name, policy) of a run directory (its learner.pt) or an exported policy file."""
    try:
        policy = load_policy(path, config)
    except (ValueError, KeyError, RuntimeError) as err:
        raise EvaluationError(f"{policy_file(path)}: cannot load it as a learner: {err}") from err
    return policy.name, policy


def load_partner(spec: str, config: PursuitConfig) -> tuple[str, Any]:
    """`MODULE:CALLABLE` → (its name, what the callable returns for `config`)."""
    module_name, sep, attr = spec.rpartition(":")
    if not sep or not module_name or not attr.isidentifier():
        raise EvaluationError(f"--partner expects MODULE:CALLABLE, got {spec!r}")
    try:
        if module_name.endswith(".py") or "/" in module_name:
            file = Path(module_name)
            if not file.is_file():
                raise EvaluationError(f"--partner {spec}: no file {file}")
            loaded = importlib.util.spec_from_file_location(f"hola_partner_{file.stem}", file)
            module = importlib.util.module_from_spec(loaded)
            loaded.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as err:
        raise EvaluationError(f"--partner {spec}: cannot import {module_name}: {err}") from err
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise EvaluationError(f"--partner {spec}: {module_name} has no callable {attr}")
    partner = factory(config)
    for method in ("act", "reset"):
        if not callable(getattr(partner, method, None)):
            raise EvaluationError(f"--partner {spec}: what {attr} returns has no {method}()")
    return getattr(partner, "name", attr), partner


def pools(names: Sequence[str], partners: Sequence[str], config: PursuitConfig):
    """Pool name → {member id → policy}, for --pool names/folders and the --partner pool."""
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        try:
            out[Path(name).name if name not in POOLS else name] = load_pool(name, config)
        except PoolError as err:
            raise EvaluationError(str(err)) from err
    if partners:
        loaded = [load_partner(spec, config) for spec in partners]
        out["partners"] = {f"{n}-{k}": p for k, (n, p) in enumerate(loaded)}
    return out


# ---- episodes -------------------------------------------------------------------------------
def draw_teams(rng: np.random.Generator, episodes: int, n_p: int, members: int) -> np.ndarray:
    """[episodes, n_p] indices into [learner, member 1 … member M]: the learner (0) in a
    uniformly random seat, every other seat a uniform draw from the members (1 … M)."""
    teams = rng.integers(1, members + 1, size=(episodes, n_p))
    teams[np.arange(episodes), rng.integers(0, n_p, size=episodes)] = 0
    return teams


def seed_means(
    learner, members: list, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> dict[str, np.ndarray]:
    """Per-seed means [S] of success, collision and length with drawn teams, and of who
    collided (`CRASHES`)."""
    out: dict[str, list[float]] = {m: [] for m in (*METRICS, *CRASHES)}
    for s in seeds:
        rng = np.random.default_rng(np.random.SeedSequence([int(s), 7]))
        teams = draw_teams(rng, episodes, config.n_pursuers, len(members))
        result = rollout(config, [learner, *members], episodes, assignment=teams, seed=int(s))
        for m in METRICS:
            out[m].append(float(np.mean(getattr(result, m))))
        learner_seat = teams == 0  # the learner is candidate 0, in one seat per episode
        out["learner_crash"].append(float(result.crashed[learner_seat].mean()))
        out["teammate_crash"].append(float(result.crashed[~learner_seat].mean()))
    return {m: np.asarray(v) for m, v in out.items()}


def bootstrap_ci(values: np.ndarray, draws: int = 10_000, seed: int = 0) -> tuple[float, float]:
    """95 % percentile bootstrap interval of the mean over the given per-seed values."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, values.size, size=(draws, values.size))
    means = values[idx].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


# ---- BR-Prox score --------------------------------------------------------------------------
@dataclass(frozen=True)
class Cells:
    """Team returns per (combination, seat, seed) cell: of each pool member in the seat
    (`reference`, [C, n_p, S, M]) and of the learner (`learner`, [C, n_p, S])."""

    combos: list[tuple[int, ...]]
    reference: np.ndarray
    learner: np.ndarray


def cell_returns(
    candidates: list, members: list, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> np.ndarray:
    """Mean team return [C, n_p, S, K] of each candidate k sitting in seat j with member
    combination c (ordered over the other seats) in the rest. Every (c, j, k) block plays
    the same `episodes` episode seeds: common random numbers for the ratio R / R(ref)."""
    n_p, k_count, m_count = config.n_pursuers, len(candidates), len(members)
    combos = list(itertools.product(range(m_count), repeat=n_p - 1))
    teams = [
        [k_count + m for m in combo[:seat]] + [k] + [k_count + m for m in combo[seat:]]
        for combo in combos
        for seat in range(n_p)
        for k in range(k_count)
    ]
    assignment = np.repeat(np.asarray(teams), episodes, axis=0)
    out = np.zeros((len(combos), n_p, len(seeds), k_count))
    for si, s in enumerate(seeds):
        block = episode_seeds(int(s), episodes)
        result = rollout(
            config,
            [*candidates, *members],
            len(assignment),
            assignment=assignment,
            episode_seeds=np.tile(block, len(teams)),
        )
        returns = result.team_return.reshape(len(combos), n_p, k_count, episodes)
        out[:, :, si, :] = returns.mean(axis=-1)
    return out


def br_prox(reference: np.ndarray, learner: np.ndarray) -> tuple[np.ndarray, int]:
    """Cell scores min(1, max(R, 0) / R_ref) over the cells with R_ref > 0 (flattened), and
    the number of cells left out for want of a reference. reference: [..., M]; learner: [...]."""
    best = reference.max(axis=-1)
    valid = best > 0
    scores = np.minimum(1.0, np.maximum(learner[valid], 0.0) / best[valid])
    return scores, int((~valid).sum())


def iqm(values: np.ndarray) -> float:
    """The interquartile mean: the mean of the middle half (scipy's trim_mean at 25 %)."""
    values = np.sort(np.asarray(values, dtype=np.float64).ravel())
    if values.size == 0:
        return float("nan")
    cut = int(values.size * 0.25)
    middle = values[cut : values.size - cut] if values.size - 2 * cut > 0 else values
    return float(middle.mean())


# ---- the command ----------------------------------------------------------------------------
def evaluate_learner(
    learner: Any,
    members: list,
    reference: np.ndarray,
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    cell_episodes: int,
) -> dict[str, Any]:
    """One learner's figures against one pool (`members`), whose reference returns
    (`cell_returns(members, members, …)`) are given: computed once for every learner."""
    per_seed = seed_means(learner, members, config, episodes, seeds)
    mine = cell_returns([learner], members, config, cell_episodes, seeds)[..., 0]
    scores, dropped = br_prox(reference, mine)
    row: dict[str, Any] = {}
    for m in (*METRICS, *CRASHES):
        v = per_seed[m]
        row[m] = float(v.mean())
        row[f"{m}_se"] = float(v.std(ddof=1) / np.sqrt(v.size)) if v.size > 1 else 0.0
        row[f"{m}_ci95"] = list(bootstrap_ci(v))
        row[f"{m}_per_seed"] = [round(float(x), 4) for x in v]
    row["score_iqm"] = iqm(scores)
    row["score_cells"] = int(scores.size)
    row["score_cells_without_reference"] = dropped
    row["episodes"] = episodes * len(seeds)
    return row


def evaluate(
    learners: Mapping[str, Any],
    pool_members: Mapping[str, Mapping[str, Any]],
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    cell_episodes: int,
    say=print,
) -> dict[str, dict[str, dict[str, Any]]]:
    """Figures per learner and pool (see the module doc)."""
    out: dict[str, dict[str, dict[str, Any]]] = {name: {} for name in learners}
    for pool, members_map in pool_members.items():
        members = list(members_map.values())
        start = time.perf_counter()
        reference = cell_returns(members, members, config, cell_episodes, seeds)
        took = time.perf_counter() - start
        say(f"[{pool}] reference returns of {len(members)} members: {took:.0f} s")
        for name, learner in learners.items():
            start = time.perf_counter()
            row = evaluate_learner(
                learner, members, reference, config, episodes, seeds, cell_episodes
            )
            out[name][pool] = row
            say(
                f"[{pool}] {name}: success {row['success']:.1%} ± {row['success_se']:.1%}, "
                f"collision {row['collision']:.1%} ± {row['collision_se']:.1%} (learner's own "
                f"{row['learner_crash']:.1%}, a teammate's {row['teammate_crash']:.1%}), length "
                f"{row['length']:.0f} ± {row['length_se']:.0f}, score IQM {row['score_iqm']:.3f}"
                f" ({time.perf_counter() - start:.0f} s)"
            )
    return out


def plot(results: Mapping[str, Mapping[str, Mapping[str, Any]]], out: Path) -> tuple[Path, Path]:
    """Fig. 4's layout: a row per pool, columns success, collision and length, one bar per
    learner with standard-error bars over seeds; and the same figures as a markdown table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    pool_names = sorted({p for r in results.values() for p in r}, key=lambda p: (p != "hot", p))
    fig, axes = plt.subplots(len(pool_names), 3, figsize=(11, 3.2 * len(pool_names)), squeeze=False)
    titles = {"success": "success rate", "collision": "collision rate", "length": "episode length"}
    labels = {"hot": "HoT (PPO pool)", "het": "HeT (heterogeneous pool)"}
    colors = plt.cm.tab10(np.arange(len(names)) % 10)
    for i, pool in enumerate(pool_names):
        for j, m in enumerate(METRICS):
            ax = axes[i, j]
            values = [results[n].get(pool, {}).get(m, np.nan) for n in names]
            errors = [results[n].get(pool, {}).get(f"{m}_se", 0.0) for n in names]
            ax.bar(range(len(names)), values, yerr=errors, color=colors, capsize=4)
            ax.set_xticks(range(len(names)), names, rotation=20, ha="right", fontsize=8)
            ax.set_title(f"{labels.get(pool, pool)}: {titles[m]}", fontsize=9)
            if m != "length":
                ax.set_ylim(0, 1)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    png = out / "evaluation.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    lines = [
        "| learner | pool | success | collision | length | score (IQM) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for n in names:
        for pool in pool_names:
            r = results[n].get(pool)
            if r:
                lines.append(
                    f"| {n} | {pool} | {r['success']:.1%} ± {r['success_se']:.1%} | "
                    f"{r['collision']:.1%} ± {r['collision_se']:.1%} | "
                    f"{r['length']:.1f} ± {r['length_se']:.1f} | {r['score_iqm']:.3f} |"
                )
    md = out / "evaluation.md"
    md.write_text("\n".join(lines) + "\n")
    return png, md


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hola_ray.evaluate", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("learners", nargs="+", type=Path, help="run directories or policy files")
    parser.add_argument("--pool", action="append", help="hot, het or a pool folder (default: both)")
    parser.add_argument("--partner", action="append", default=[], help="MODULE:CALLABLE")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--cell-episodes", type=int, default=10, help="episodes per score cell")
    parser.add_argument("--plot", action="store_true", help="Fig. 4's layout and a table")
    parser.add_argument("--out", type=Path, help="where --plot writes (default runs/evaluation-…)")
    parser.add_argument("--json", action="store_true", help="last line: the figures as JSON")
    args = parser.parse_args(argv)
    try:
        evaders = {learner_evaders(p, PursuitConfig()) for p in args.learners}
        if len(evaders) > 1:
            raise EvaluationError(
                f"the learners were trained against different numbers of evaders "
                f"({sorted(evaders)}); evaluate them separately"
            )
        config = PursuitConfig(n_evaders=evaders.pop())
        names = args.pool if args.pool else ([] if args.partner else list(POOLS))
        members = pools(names, args.partner, config)
        loaded = [load_learner(p, config) for p in args.learners]
        called = [name for name, _ in loaded]
        if len(set(called)) < len(called):  # e.g. two runs' best.pt: name them by their folder
            called = [
                f"{p.resolve().parent.name}/{name}" if called.count(name) > 1 else name
                for p, name in zip(args.learners, called, strict=True)
            ]
        if len(set(called)) < len(called):
            raise EvaluationError(
                f"two learners share a name: {', '.join(map(str, args.learners))}"
            )
        learners = {name: policy for name, (_, policy) in zip(called, loaded, strict=True)}
    except EvaluationError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"scenario: {config.n_pursuers} pursuers vs {config.n_evaders} evader(s)", flush=True)
    results = evaluate(learners, members, config, args.episodes, args.seeds, args.cell_episodes)
    if args.plot:
        out = args.out or Path("runs") / time.strftime("evaluation-%Y%m%d-%H%M%S")
        png, md = plot(results, out)
        print(f"wrote {png} and {md}")
    if args.json:
        keep = [k for m in (*METRICS, *CRASHES) for k in (m, f"{m}_se")]
        print(
            json.dumps(
                {
                    "runs": {
                        n: {
                            p: {k: round(v[k], 4) for k in keep}
                            | {"score_iqm": round(v["score_iqm"], 4)}
                            for p, v in r.items()
                        }
                        for n, r in results.items()
                    }
                }
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
