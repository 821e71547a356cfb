"""The paper's experiment on Ray: every method × seed, then the zero-shot evaluation.

    python -m hola_ray.experiment --config configs/experiments/X.yaml [--out DIR]
    python -m hola_ray.experiment --resume DIR
    python -m hola_ray.experiment --resume DIR --stop-short   # end before the plan: evaluate

The experiment config and what the command does: `hola_ray.experiment`'s doc.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from hola_ray.cli import OneLineParser, port

if TYPE_CHECKING:
    from hola_ray.experiment.config import Experiment


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    # imported here and in the helpers, not above: `script` re-runs the command under the
    # fixed hash seed before torch, Ray and RLlib (which the experiment's methods import) load
    from hola_ray.cli import require_free_port
    from hola_ray.config.reader import ConfigError
    from hola_ray.experiment.runner import Runner

    try:
        experiment, out = _experiment_and_dir(args)
        require_free_port(args.metrics_port, "--metrics-port")
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.resume is None:
        _save_config(experiment, out)
    from hola_ray.process import NAMESPACE, init_ray

    init_ray(NAMESPACE, args.num_cpus, metrics_port=args.metrics_port)
    trials = experiment.trials()
    print(
        f"experiment in {out}: {len(experiment.methods)} method(s) × {len(experiment.seeds)} "
        f"seed(s) = {len(trials)} trials; base {experiment.base}",
        flush=True,
    )
    try:
        runner = Runner(experiment, out, say=lambda s: print(s, flush=True))
        if args.stop_short:
            runner.stop_short()
        else:
            runner.run()
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


def _parser() -> OneLineParser:
    parser = OneLineParser(
        prog="python -m hola_ray.experiment", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--config", type=Path, help="experiment YAML (configs/experiments/)")
    parser.add_argument("--out", type=Path, help="experiment directory (default runs/<name>-…)")
    parser.add_argument("--resume", type=Path, metavar="DIR", help="continue an experiment")
    parser.add_argument(
        "--stop-short",
        action="store_true",
        help="with --resume: train nothing more; evaluate the seeds whose every method is "
        "done and write the results marked as stopped short of the plan",
    )
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local Ray (default: all)")
    parser.add_argument(
        "--metrics-port",
        type=port,
        metavar="PORT",
        help="serve the trials' figures (hola_ray_*) and Ray's as Prometheus text on "
        "127.0.0.1:PORT/metrics (a local Ray; a cluster's port is its own)",
    )
    return parser


def _experiment_and_dir(args: argparse.Namespace) -> tuple[Experiment, Path]:
    """The experiment and its directory: a resumed one's saved config, or a new one's
    YAML and a fresh directory (made here, so that an --out that cannot be made fails
    before Ray starts). A ConfigError says what of the command line does not fit."""
    from hola_ray.cli import make_dir
    from hola_ray.config.reader import ConfigError
    from hola_ray.experiment.config import CONFIG_NAME, Experiment
    from hola_ray.homes import RUNS

    if args.stop_short and args.resume is None:
        raise ConfigError("--stop-short ends an experiment under way: give --resume DIR")
    if args.resume is not None:
        if args.config is not None or args.out is not None:
            raise ConfigError("--resume DIR takes the experiment's own config; drop --config")
        saved = args.resume / CONFIG_NAME
        if not saved.is_file():
            raise ConfigError(f"--resume {args.resume}: no {CONFIG_NAME} there")
        return Experiment.from_yaml(saved), args.resume
    if args.config is None:
        raise ConfigError("give --config configs/experiments/X.yaml or --resume DIR")
    experiment = Experiment.from_yaml(args.config)
    out = args.out or RUNS / time.strftime(f"{args.config.stem}-%Y%m%d-%H%M%S")
    if (out / CONFIG_NAME).is_file():
        raise ConfigError(f"{out} already holds an experiment; continue it with --resume")
    make_dir(out)
    return experiment, out


def _save_config(experiment: Experiment, out: Path) -> None:
    """OUT/config.yaml, what --resume reads back: the base, the overrides and the plan, with
    tuples as lists so that it is plain YAML."""
    from hola_ray.experiment.config import CONFIG_NAME
    from hola_ray.homes import ROOT

    out.mkdir(parents=True, exist_ok=True)
    # the base is resolved now, so that the saved copy does not depend on where it
    # lives; one inside the repository is saved relative to it (`Experiment.base_path`
    # reads it so), so that a published copy names no path of this machine
    base = experiment.base_path().resolve()
    if base.is_relative_to(ROOT.resolve()):
        base = base.relative_to(ROOT.resolve())
    saved = {
        "base": str(base),
        "overrides": experiment.overrides,
        "methods": experiment.methods,
        "seeds": list(experiment.seeds),
        "parallel": experiment.parallel,
        "evaluation": "none"
        if experiment.evaluation is None
        else {
            k: [list(x) if isinstance(x, tuple) else x for x in v] if isinstance(v, tuple) else v
            for k, v in experiment.evaluation.__dict__.items()
        },
    }
    (out / CONFIG_NAME).write_text(yaml.safe_dump(saved, sort_keys=False))


def script() -> None:
    """`hola-experiment` (`[project.scripts]`): `main` under the fixed hash seed, as `python -m
    hola_ray.experiment` runs it (`hola_ray.process.fixed_hash_seed`)."""
    from hola_ray.process import fixed_hash_seed, leave, pause_collector

    fixed_hash_seed("hola_ray.experiment", sys.argv[1:])
    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
