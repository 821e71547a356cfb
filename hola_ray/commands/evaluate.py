"""Zero-shot evaluation against unseen teammate pools (paper §V, Fig. 4; docs/contract.md §5).

    python -m hola_ray evaluate RUN_DIR|POLICY.pt [...] [--pool hot|het|DIR ...]
        [--partner MODULE:CALLABLE ...] [--episodes 50] [--seeds 0 1 2]
        [--plot] [--out DIR] [--json]
    python -m hola_ray evaluate --protocol open-teams RUN_DIR|POLICY.pt [...]
        [--arenas open bar blocks paper] [--modes zero-shot open] [--sizes 2 3 4 5]
        [--evaders N] [--episodes 50] [--seeds 0 1 2] [--out DIR]

Per learner and pool, `--episodes` episodes per seed with teammates drawn from the pool,
and the BR-Prox score over `--cell-episodes` per cell: what each figure means and how its
interval is made is `hola_ray.evaluation.zero_shot`'s docstring. Beside every learner, the
learner's scale (`hola_ray.evaluation.scale`): the same episodes played by a seat that holds
its heading (the floor) and by the committed ceilings (`pools/reference/`), and the
learner's normalised score (learner − floor) / (ceiling − floor) with its interval.

The scenario is the one the learners trained in (`policies.registry.trained_scenario`:
the paper's evaluation is 3 vs 2 in Table I's arena; every learner given must share it)
with the arena's default rewards (the team return that the score compares; a run's own
reward shaping is not used).
Pool members trained for another team (more or fewer evaders or teammates) play it
through `hola_ray.policies.adapter.ScenarioAdapter`.

`--protocol open-teams` plays contract §6.4 instead: every arena, team size and mode
(zero-shot, open), per pool, with AT-Drone's SUC, COL, AST and REW, the learner's scale,
and every pair of learners' differences, per cell and over each mode's cells
(`hola_ray.evaluation.open_teams`). It writes results.json, results.md and one figure per
arena to --out. Learners trained for any team play it, through the adapter where their
observation differs.

A learner is a run directory (its final `learner.pt`), a generation folder or a policy
file: a learned pursuer's export or a D3QN-G export (which reads the first evader and
plays any number). `--partner MODULE:CALLABLE` (repeatable; MODULE a module name or a path
to a .py file) adds a teammate of your own: the callable gets the `PursuitConfig` and
returns an object with `act(obs) → actions [N]` and `reset(mask)`; the partners form a pool
named `partners`. Every bad input (a missing or unreadable file, an unknown pool, a partner
that cannot be made or acts wrongly) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.compare import METRICS
from hola_ray.evaluation.players import EvaluationError, load_learner, pools
from hola_ray.evaluation.pools import EVALUATION_POOLS, PoolError
from hola_ray.evaluation.report import plot
from hola_ray.evaluation.rollout import PolicyError
from hola_ray.evaluation.scale import load_references
from hola_ray.evaluation.zero_shot import evaluate
from hola_ray.homes import RUNS
from hola_ray.policies.registry import played_scenario


def learners_scenario(paths: list[Path]) -> PursuitConfig:
    """The scenario the learners trained in, with the default reward (`played_scenario`);
    D3QN-G learners play any: the others' scenario, else the paper's. Learners of different
    scenarios are evaluated separately."""
    scenarios: list[PursuitConfig] = []
    for path in paths:
        try:
            scenario = played_scenario(path)
        except ValueError as err:
            raise EvaluationError(str(err)) from err
        if scenario is not None and scenario not in scenarios:
            scenarios.append(scenario)
    if len(scenarios) > 1:
        evaders = sorted({s.n_evaders for s in scenarios})
        what = f"against different numbers of evaders ({evaders})" if len(evaders) > 1 else ""
        raise EvaluationError(
            f"the learners were trained in different scenarios {what}".rstrip()
            + "; evaluate them separately"
        )
    return scenarios[0] if scenarios else PursuitConfig()


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m hola_ray evaluate", description=__doc__.split("\n\n")[0])
    parser.add_argument("learners", nargs="+", type=Path, help="run directories or policy files")
    parser.add_argument("--pool", action="append", help="hot, het or a pool folder (default: both)")
    parser.add_argument("--partner", action="append", default=[], help="MODULE:CALLABLE")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--cell-episodes", type=int, default=10, help="episodes per score cell")
    parser.add_argument("--plot", action="store_true", help="Fig. 4's layout and a table")
    parser.add_argument("--out", type=Path, help="where --plot writes (default runs/evaluation-…)")
    parser.add_argument("--json", action="store_true", help="last line: the figures as JSON")
    parser.add_argument(
        "--protocol", choices=("zero-shot", "open-teams"), default="zero-shot", help="see above"
    )
    parser.add_argument("--arenas", nargs="+", help="open-teams: the arenas (default: all four)")
    parser.add_argument("--modes", nargs="+", help="open-teams: zero-shot, open (default: both)")
    parser.add_argument("--sizes", type=int, nargs="+", help="open-teams: seats (default: 2-5)")
    parser.add_argument(
        "--evaders", type=int, help="open-teams: evaders (default: the learners' own)"
    )
    parser.add_argument("--horizon", type=int, help="open-teams: shorter episodes (tests)")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.cell_episodes < 1:
        return fail("--episodes and --cell-episodes must be at least 1")
    if args.protocol == "open-teams":
        return open_teams(args)
    try:
        config = learners_scenario(args.learners)
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
        references = load_references(config)
        results = evaluate(
            learners,
            members,
            config,
            args.episodes,
            args.seeds,
            args.cell_episodes,
            references=references,
        )
    except (EvaluationError, PolicyError, PoolError) as err:
        return fail(str(err))
    if args.plot:
        out = args.out or RUNS / time.strftime("evaluation-%Y%m%d-%H%M%S")
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
                            | _scale(v)
                            for p, v in r.items()
                        }
                        for n, r in results.items()
                    }
                }
            )
        )
    return 0


def grid_scenario(paths: list[Path], evaders: int | None) -> PursuitConfig:
    """The scenario the open-team grid plays: the learners' own (`played_scenario`), which
    may differ in the team and the arena only, with `evaders` where given; the paper's for
    D3QN-G learners alone."""
    from hola_ray.evaluation.open_teams import grid_base
    from hola_ray.policies.registry import played_scenario

    scenarios = []
    for path in paths:
        try:
            scenario = played_scenario(path)
        except ValueError as err:
            raise EvaluationError(str(err)) from err
        if scenario is not None:
            if evaders is not None:
                scenario = dataclasses.replace(scenario, n_evaders=evaders, obs_evaders=None)
            scenarios.append(scenario)
    if not scenarios:
        return PursuitConfig(n_evaders=evaders or 2)
    try:
        return grid_base(scenarios)
    except ValueError as err:
        raise EvaluationError(f"{err}: evaluate them separately, or give --evaders") from err


def open_teams(args: argparse.Namespace) -> int:
    """`--protocol open-teams` (module doc): every cell played, then written to --out."""
    from hola_ray.config.reader import ConfigError
    from hola_ray.config.scenario import ARENAS
    from hola_ray.evaluation import open_teams as protocol

    arenas = args.arenas or list(ARENAS)
    modes = args.modes or list(protocol.MODES)
    sizes = args.sizes or list(protocol.SIZES)
    for given, known, what in (
        (arenas, ARENAS, "--arenas"),
        (modes, protocol.MODES, "--modes"),
        (sizes, protocol.SIZES, "--sizes"),
    ):
        unknown = [x for x in given if x not in known]
        if unknown:
            return fail(f"{what}: unknown {unknown}; give any of {list(known)}")
    if args.partner:
        return fail("--partner is for the zero-shot protocol; give pools with --pool")
    try:
        base = grid_scenario(args.learners, args.evaders)
        if args.horizon is not None:
            base = dataclasses.replace(base, horizon=args.horizon)  # checked on creation
        learners = {}
        for path in args.learners:
            name = path.stem if path.is_file() else path.name
            if path.is_file() and path.parent.name not in ("", "."):
                name = f"{path.parent.name}/{path.stem}"
            learners[name] = protocol.learner_loader(path)
        results = protocol.run_protocol(
            learners,
            args.pool or list(EVALUATION_POOLS),
            base,
            args.episodes,
            args.seeds,
            arenas,
            modes,
            sizes,
            say=lambda line: print(line, flush=True),
        )
    except (ConfigError, EvaluationError, PolicyError, PoolError, ValueError) as err:
        return fail(str(err))
    out = args.out or RUNS / time.strftime("open-teams-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=1, allow_nan=True))
    written = protocol.report(results, out)
    print(f"wrote {out / 'results.json'}, " + ", ".join(str(p) for p in written))
    for mode_pool, by_pair in results["leads"].items():
        for pair, d in by_pair.items():
            diff = d["difference"]["success"]
            print(
                f"{mode_pool}: {pair} success {diff['mean']:+.1%} "
                f"[{diff['ci95'][0]:+.1%}, {diff['ci95'][1]:+.1%}] over {d['cells']} cells: "
                f"{diff['verdict']}"
            )
    return 0


def _scale(row: Mapping[str, Any]) -> dict[str, Any]:
    """The learner's scale for the JSON line: the reference seats' figures and the
    normalised score per ceiling."""
    if "scale" not in row:
        return {}
    scale = row["scale"]
    return {
        "scale": {
            "floor": scale["floor"],
            "ceilings": scale["ceilings"],
            "normalised": {
                c: {"mean": round(v["mean"], 4), "ci95": [round(x, 4) for x in v["ci95"]]}
                for c, v in scale["normalised"].items()
            },
        }
    }


def _rounded(values: Mapping[str, Any]) -> dict[str, Any]:
    """Figures to 4 decimals for the JSON line (lists element-wise; NaN stays NaN)."""
    return {
        k: [round(float(x), 4) for x in v] if isinstance(v, list | tuple) else round(float(v), 4)
        for k, v in values.items()
    }


def script() -> None:
    """`hola-eval` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
