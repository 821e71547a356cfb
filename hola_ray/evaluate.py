"""Zero-shot evaluation against unseen teammate pools (paper §V, Fig. 4; SPEC §5).

    python -m hola_ray.evaluate RUN_DIR|POLICY.pt [...] [--pool hot|het|DIR ...]
        [--partner MODULE:CALLABLE ...] [--episodes 50] [--seeds 0 1 2]
        [--plot] [--out DIR] [--json]

Per learner and pool, `--episodes` episodes per seed: the learner sits in a random seat
and its n_p − 1 teammates are drawn from the pool, uniformly with replacement, per episode.
The figures are means over every episode: success, collision (any seat crashed), length,
AT-Drone's `steps_success` (mean length over successful episodes: AST) and `reward` (mean
per-pursuer return: REW), and whose crashes (`learner_crash`: the learner's own seat;
`teammate_crash`: the share of teammate seats). Standard errors and 95 % intervals come
from a bootstrap over episodes resampled within each partner combination
(`hola_ray.evaluation.compare`). Every learner plays the same episodes (the draws depend on
the seed only), so two learners' figures are paired.

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

A learner is a run directory (its final `learner.pt`), a generation folder or a policy
file: a learned pursuer's export or a D3QN-G export (which reads the first evader and
plays any number). `--partner MODULE:CALLABLE` (repeatable; MODULE a module name or a path
to a .py file) adds a teammate of your own: the callable gets the `PursuitConfig` and
returns an object with `act(obs) → actions [N]` and `reset(mask)`; the partners form a pool
named `partners`. Every bad input (a missing or unreadable file, an unknown pool, a partner
that cannot be made or acts wrongly) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import importlib
import importlib.util
import itertools
import json
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hola_ray.cli import OneLineParser, fail
from hola_ray.env.config import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.compare import FIELDS, METRICS, compare
from hola_ray.evaluation.pools import (
    EVALUATION_POOLS,
    POOLS,
    PoolError,
    load_pool,
    pool_dir,
    sha256,
)
from hola_ray.evaluation.rollout import PolicyError, rollout
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.evaluation.teams import play
from hola_ray.policies.d3qn import FORMAT as D3QN_FORMAT
from hola_ray.policies.registry import load_export, load_policy, policy_file


class EvaluationError(RuntimeError):
    """A command line that cannot be evaluated: one clear message."""


# ---- who plays ------------------------------------------------------------------------------
def learner_evaders(path: Path, config: PursuitConfig) -> int | None:
    """How many evaders a learner was trained against (its run's config, or the export's
    input size): the evaluation plays that scenario. None for a D3QN-G export, which reads
    the first evader only and plays any number."""
    path = Path(path)
    if not path.exists():
        raise EvaluationError(f"{path}: no such file or directory")
    if path.is_dir() and (path / "config.yaml").is_file():
        import yaml

        env = (yaml.safe_load((path / "config.yaml").read_text()) or {}).get("env") or {}
        return int(env.get("n_evaders", config.n_evaders))
    file = policy_file(path)
    try:
        export = load_export(path)
    except ValueError as err:
        raise EvaluationError(str(err)) from err
    if export.get("format") == D3QN_FORMAT:
        return None
    if not isinstance(export.get("weights"), list | tuple) or not export["weights"]:
        raise EvaluationError(f"{file}: not a policy export (no weights)")
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


def probe(policy: Any, name: str, config: PursuitConfig) -> None:
    """Play `policy` on a few real observations: its actions must be a finite [N] array."""
    env = BatchedPursuit(config, 4)
    obs = env.reset(seeds=np.arange(4)).reshape(-1, config.obs_dim)
    try:
        policy.reset(np.ones(len(obs), dtype=bool))
        actions = policy.act(obs)
    except Exception as err:  # noqa: BLE001 - a user's code: any failure is one line
        raise EvaluationError(f"{name}: act failed on {obs.shape} observations: {err!r}") from err
    try:
        PolicyError.check(name, actions, len(obs))
    except PolicyError as err:
        raise EvaluationError(str(err)) from err


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
    except Exception as err:  # noqa: BLE001 - the module's own code raised on import
        raise EvaluationError(f"--partner {spec}: importing {module_name} failed: {err!r}") from err
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise EvaluationError(f"--partner {spec}: {module_name} has no callable {attr}")
    try:
        partner = factory(config)
    except Exception as err:  # noqa: BLE001 - a user's factory: any failure is one line
        raise EvaluationError(f"--partner {spec}: {attr}(config) raised {err!r}") from err
    for method in ("act", "reset"):
        if not callable(getattr(partner, method, None)):
            raise EvaluationError(f"--partner {spec}: what {attr} returns has no {method}()")
    probe(partner, f"--partner {spec}", config)
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


# ---- BR-Prox score --------------------------------------------------------------------------
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
    played = play(learner, members, config, episodes, seeds)
    mine = cell_returns([learner], members, config, cell_episodes, seeds)[..., 0]
    scores, dropped = br_prox(reference, mine)
    intervals = compare({"learner": [played]})[0]["learner"]
    row: dict[str, Any] = {}
    for m in METRICS:
        row[m] = intervals[m]["mean"]
        row[f"{m}_se"] = intervals[m]["se"]
        row[f"{m}_ci95"] = intervals[m]["ci95"]
        if m != "steps_success":
            row[f"{m}_per_seed"] = [
                round(float(played[m][played["eval_seed"] == s].mean()), 4) for s in seeds
            ]
    row["score_iqm"] = iqm(scores)
    row["score_cells"] = int(scores.size)
    row["score_cells_without_reference"] = dropped
    row["episodes"] = episodes * len(seeds)
    row["per_episode"] = {
        m: [round(float(x), 4) for x in played[m]]
        if m in ("reward", "teammate_crash")
        else [int(x) for x in played[m]]
        for m in (*FIELDS, "eval_seed")
    }
    return row


def pool_fingerprints(names: Sequence[str]) -> dict[str, str]:
    """Pool name → the sha256 of its manifest (which holds every member file's sha256): an
    evaluation cached under one fingerprint is stale once the pool is rebuilt."""
    return {name: sha256(pool_dir(name) / "manifest.json") for name in names}


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
                f"{row['length']:.0f} ± {row['length_se']:.0f} (successful episodes "
                f"{row['steps_success']:.0f}), reward {row['reward']:.1f}, score IQM "
                f"{row['score_iqm']:.3f} ({time.perf_counter() - start:.0f} s)"
            )
    return out


PANELS = {
    "success": "success rate",
    "collision": "collision rate",
    "length": "episode length",
    "steps_success": "steps to success (AST)",
    "reward": "per-pursuer return (REW)",
}
"""Fig. 4's three columns, then AT-Drone's two"""


def table_lines(results: Mapping[str, Mapping[str, Mapping[str, Any]]], first: str) -> list[str]:
    """A markdown table of every learner's (method's) figures with their 95 % intervals."""

    def cell(r: Mapping[str, Any], m: str) -> str:
        value, (lo, hi) = r[m], r.get(f"{m}_ci95", (float("nan"),) * 2)
        if m in ("length", "steps_success", "reward"):
            return f"{value:.1f} [{lo:.1f}, {hi:.1f}]"
        return f"{value:.1%} [{lo:.1%}, {hi:.1%}]"

    pool_names = sorted({p for r in results.values() for p in r}, key=lambda p: (p != "hot", p))
    lines = [
        f"| {first} | pool | success | collision | length | steps to success | reward "
        "| learner crashed | score (IQM) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for n, by_pool in results.items():
        for pool in pool_names:
            r = by_pool.get(pool)
            if r:
                cells = " | ".join(cell(r, m) for m in (*PANELS, "learner_crash") if m in r)
                score = r.get("score_iqm", r.get("score", float("nan")))
                lines.append(f"| {n} | {pool} | {cells} | {score:.3f} |")
    return lines


def plot(results: Mapping[str, Mapping[str, Mapping[str, Any]]], out: Path) -> tuple[Path, Path]:
    """Fig. 4's layout (a row per pool; success, collision, length) and AT-Drone's steps to
    success and reward, one bar per learner with its 95 % interval; and the same figures
    as a markdown table (`evaluation.md`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    pool_names = sorted({p for r in results.values() for p in r}, key=lambda p: (p != "hot", p))
    fig, axes = plt.subplots(
        len(pool_names), len(PANELS), figsize=(17, 3.2 * len(pool_names)), squeeze=False
    )
    labels = {"hot": "HoT", "het": "HeT"}
    colors = plt.cm.tab10(np.arange(len(names)) % 10)
    for i, pool in enumerate(pool_names):
        for j, (m, title) in enumerate(PANELS.items()):
            ax = axes[i, j]
            rows = [results[n].get(pool, {}) for n in names]
            values = np.array([r.get(m, np.nan) for r in rows], dtype=np.float64)
            bounds = np.array(
                [r.get(f"{m}_ci95", (np.nan, np.nan)) for r in rows], dtype=np.float64
            ).reshape(len(names), 2)
            errors = np.nan_to_num(np.abs(bounds - values[:, None]).T)
            ax.bar(range(len(names)), values, yerr=errors, color=colors, capsize=4)
            ax.set_xticks(range(len(names)), names, rotation=20, ha="right", fontsize=8)
            ax.set_title(f"{labels.get(pool, pool)}: {title}", fontsize=9)
            if m in ("success", "collision"):
                ax.set_ylim(0, 1)
    fig.suptitle("bars: mean; whiskers: 95 % interval (stratified bootstrap)", fontsize=9)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    png = out / "evaluation.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    md = out / "evaluation.md"
    md.write_text("\n".join(table_lines(results, "learner")) + "\n")
    return png, md


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m hola_ray.evaluate", description=__doc__.split("\n\n")[0])
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
    if args.episodes < 1 or args.cell_episodes < 1:
        return fail("--episodes and --cell-episodes must be at least 1")
    try:
        evaders = {learner_evaders(p, PursuitConfig()) for p in args.learners} - {None}
        if len(evaders) > 1:
            raise EvaluationError(
                f"the learners were trained against different numbers of evaders "
                f"({sorted(evaders)}); evaluate them separately"
            )
        # D3QN-G learners play any number of evaders: the others' scenario, else the paper's
        config = PursuitConfig(n_evaders=evaders.pop()) if evaders else PursuitConfig()
        names = args.pool if args.pool else ([] if args.partner else list(EVALUATION_POOLS))
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
        print(f"scenario: {config.n_pursuers} pursuers vs {config.n_evaders} evader(s)", flush=True)
        results = evaluate(learners, members, config, args.episodes, args.seeds, args.cell_episodes)
    except (EvaluationError, PolicyError) as err:
        return fail(str(err))
    if args.plot:
        out = args.out or Path("runs") / time.strftime("evaluation-%Y%m%d-%H%M%S")
        png, md = plot(results, out)
        print(f"wrote {png} and {md}")
    if args.json:
        keep = [k for m in METRICS for k in (m, f"{m}_se", f"{m}_ci95")]
        print(
            json.dumps(
                {
                    "runs": {
                        n: {
                            p: _rounded({k: v[k] for k in keep})
                            | {"score_iqm": round(v["score_iqm"], 4)}
                            for p, v in r.items()
                        }
                        for n, r in results.items()
                    }
                }
            )
        )
    return 0


def _rounded(values: Mapping[str, Any]) -> dict[str, Any]:
    """Figures to 4 decimals for the JSON line (lists element-wise; NaN stays NaN)."""
    return {
        k: [round(float(x), 4) for x in v] if isinstance(v, list | tuple) else round(float(v), 4)
        for k, v in values.items()
    }


if __name__ == "__main__":
    sys.exit(main())
