"""The main job: train a zero-shot pursuer with HOLA-Drone on Ray.

    python -m hola_ray.run [--config configs/X.yaml] [--out DIR] [--resume RUN_DIR]

With no `RAY_ADDRESS` it starts a local Ray (the laptop case); with one it joins that
cluster (`ray job submit` sets it). With no --config it runs the embedded default, the
same as configs/default.yaml: a small run that finishes in about 5 minutes on 2 CPUs.
The config is validated before Ray starts.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hola_ray import interrupt
from hola_ray.cli import OneLineParser, apply_sets, make_dir, port, require_free_port
from hola_ray.config.reader import ConfigError, load_yaml, located
from hola_ray.homes import RUNS

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig

DEFAULT: dict[str, Any] = {
    "method": "hola",
    "generations": 8,
    "seed": 0,
    "env": {
        "n_pursuers": 3,
        "n_evaders": 1,
        "reward": {"obstacle_penalty": 0.5, "teammate_penalty": 0.5, "approach": "distance"},
    },
    "oracle": {
        "budget": "learner_samples",
        "env_steps": 100_000,
        "train_batch": 8192,
        "minibatch": 1024,
        "epochs": 10,
        "lr": 1e-3,
        "entropy_coef": 0.0,
        "vf_coef": 0.5,
        "hidden": [64, 64],
        "envs_per_runner": 64,
        "overlap": True,
    },
    "pretrain": {
        "env_steps": 100_000,
        "alpha": 0.05,
        "population": "mep-3v1-s0",
        "learner_start": "member",
    },
    "population": {"max_size": 6, "initial_size": 4, "top_m": 3},
    "grapher": {"episodes_per_edge": 64, "workers": 2},
}
"""The embedded default run (configs/default.yaml holds the same)."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = OneLineParser(prog="python -m hola_ray.run", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", type=Path, help="run config YAML (default: embedded)")
    parser.add_argument("--out", type=Path, help="run directory (default runs/<method>-<time>)")
    parser.add_argument(
        "--resume", type=Path, metavar="RUN_DIR", help="continue a run after its last generation"
    )
    parser.add_argument(
        "--generations",
        type=int,
        metavar="N",
        help="train until generation N (with --resume: extend a run, finished or not)",
    )
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local Ray (default: all)")
    parser.add_argument(
        "--dashboard",
        action="store_true",
        help="start the local Ray with its dashboard (2-3 s more; a cluster has its own)",
    )
    parser.add_argument(
        "--no-dashboard",
        action="store_true",
        help="without the dashboard (the default)",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="SECTION.FIELD=VALUE",
        help="override one config value, read as YAML (repeatable): --set oracle.lr=1e-4 "
        "--set env.reward.approach=distance --set method=sp",
    )
    parser.add_argument(
        "--metrics-port",
        type=port,
        metavar="PORT",
        help="serve the run's figures (hola_ray_*) and Ray's as Prometheus text on "
        "127.0.0.1:PORT/metrics (a local Ray; a cluster's port is its own)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    return parser.parse_args(argv)


class RunError(RuntimeError):
    """A run cannot start or continue as asked (e.g. a run directory already in use)."""


def check_run_dir(run_dir: Path, resume: bool) -> None:
    """Refuse to start a fresh run over a run directory that has generations."""
    from hola_ray.population.rundir import RunDir

    run = RunDir(run_dir)
    if resume:
        if not run.config.is_file():
            raise RunError(f"--resume {run_dir}: no config.yaml there, not a run directory")
    elif run.completed():
        raise RunError(
            f"{run_dir} already holds generations {run.completed()}; "
            f"continue it with --resume {run_dir} or pick another --out"
        )


def resolve(args: argparse.Namespace) -> tuple[RunConfig, Path]:
    """The validated config and run directory; raises before any work starts."""
    from hola_ray.methods.config import RunConfig

    if args.resume is not None:
        if args.config is not None or args.out is not None or args.set:
            raise ConfigError(
                "--resume RUN_DIR takes the run's own config and directory; drop --config, "
                "--out and --set"
            )
        check_run_dir(args.resume, resume=True)
        config = RunConfig.from_yaml(args.resume / "config.yaml")
        if args.generations is not None:
            config = with_generations(config, args.generations)
        return config, args.resume
    config = read_config(args.config, args.set)
    if args.generations is not None:
        config = with_generations(config, args.generations)
    out = args.out or RUNS / time.strftime(f"{config.method}-%Y%m%d-%H%M%S")
    check_run_dir(out, resume=False)
    make_dir(out)
    return config, out


def read_config(path: Path | None, sets: list[str] | None) -> RunConfig:
    """The run config of `--config` (the embedded default without one) with `--set`'s
    overrides; an error names the file and line, or the `--set` it came from."""
    from hola_ray.methods.config import RunConfig

    if not sets:
        return RunConfig.from_dict(DEFAULT) if path is None else RunConfig.from_yaml(path)
    data = DEFAULT if path is None else load_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path} is empty or not a mapping: a run config needs its method")
    try:
        data = apply_sets(data, sets)
    except ValueError as err:
        raise ConfigError(str(err)) from None
    try:
        return RunConfig.from_dict(data)
    except ConfigError as err:
        set_paths = {s.partition("=")[0].strip() for s in sets}
        field = err.field or ""
        if any(field == p or field.startswith(p + ".") for p in set_paths):
            raise ConfigError(f"--set: {err}", err.field) from None
        raise (located(err, path) if path is not None else err) from None


def with_generations(config: RunConfig, generations: int) -> RunConfig:
    """The config with `--generations N` (validated as the config's own field)."""
    from hola_ray.methods.config import RunConfig

    return RunConfig.from_dict({**config.to_dict(), "generations": generations})


def finished(out: Path, config: RunConfig) -> bool:
    """A resumed run that already holds its last generation: say so instead of starting.
    One killed just after committing it, before learner.pt, is not finished: the trainer
    writes that file again and trains nothing more."""
    from hola_ray.population.rundir import RunDir

    run = RunDir(out)
    if not run.finished(config.generations):
        return False
    last = run.last_completed()
    print(
        f"{out} is finished: generation {last} of {config.generations} is done; train it "
        f"further with --resume {out} --generations {last + 1} (or more)",
        flush=True,
    )
    return True


def init_ray(args: argparse.Namespace) -> type:
    """Join RAY_ADDRESS's cluster if set, else start a local Ray; returns the `Trainer`
    class, imported (RLlib, 1.5 s) while Ray starts (`hola_ray.process.init_ray_importing`)."""
    from hola_ray.process import NAMESPACE, init_ray_importing

    url, trainer = init_ray_importing(
        "hola_ray.methods.trainer",
        NAMESPACE,
        args.num_cpus,
        args.dashboard and not args.no_dashboard,
        args.metrics_port,
    )
    if url:
        print(f"Ray dashboard: {url}", flush=True)
    return trainer.Trainer


def main(argv: list[str] | None = None, started: float | None = None) -> int:
    """The command; `started`: when the process began (`time.perf_counter()`), so the
    run's first metrics row counts the imports and Ray's start."""
    args = parse_args(argv)
    try:
        config, out = resolve(args)
        require_free_port(args.metrics_port, "--metrics-port")
    except (ConfigError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.resume is not None and finished(out, config):
        return 0
    from hola_ray.methods.generation_zero import resolve as resolve_zero
    from hola_ray.population.rundir import RunDir

    try:  # where generation 0 comes from, before Ray starts: a refused population is one line
        zero = resolve_zero(config, RunDir(out))
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    from hola_ray.population.lock import RunDirLocked, RunLock

    lock = RunLock(out)
    try:
        note = lock.acquire()  # before Ray starts and before anything is written
    except RunDirLocked as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if note:
        print(note, flush=True)
    try:
        Trainer = init_ray(args)
        interrupt.install()  # after ray.init: a Ctrl-C swallowed inside Ray is not lost

        print(
            f"training run in {out}: method {config.method}, {config.generations} "
            f"generations, {config.oracle.env_steps:,} env steps per oracle",
            flush=True,
        )
        Trainer(config, out, not args.quiet, lock, started=started, zero=zero).fit()
    except KeyboardInterrupt:
        return interrupted(out)
    except OSError as err:  # a failed write, here or in the coordinator (a Ray task's error)
        return write_failed(out, err)
    finally:
        lock.release()
    print(f"done: learner {out / 'learner.pt'}; status: python -m hola_ray status {out}")
    return 0


def write_failed(out: Path, err: OSError) -> int:
    """A write that failed (a full disk, a path blocked): one line naming the file and what
    is saved; the generation being written is absent or whole, never half (its folder is
    renamed into place), so --resume goes on from the last complete one; 1."""
    import ray

    from hola_ray.population.rundir import RunDir

    cause = getattr(err, "cause", None) or err  # a Ray task's error carries the OSError
    # a rename names its source first: the file meant is the target
    path = getattr(cause, "filename2", None) or getattr(cause, "filename", None) or "a file"
    why = getattr(cause, "strerror", None) or str(cause).strip().splitlines()[-1]
    done = RunDir(out).completed()
    saved = f"generations {done[0]}–{done[-1]} are saved" if done else "no generation is saved"
    print(
        f"error: writing {path} failed ({why}); {saved} in {out}; once it can be written, "
        f"continue with: python -m hola_ray.run --resume {out}",
        file=sys.stderr,
        flush=True,
    )
    ray.shutdown()
    return 1


def interrupted(out: Path) -> int:
    """Ctrl-C: one line on what is saved and how to go on; Ray's workers stopped; 130."""
    import signal

    import ray

    from hola_ray.population.rundir import RunDir

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the cleanup
    done = RunDir(out).completed()
    saved = f"generations {done[0]}–{done[-1]} are saved" if done else "no generation is saved"
    print(
        f"\ninterrupted: {saved} in {out}; continue with: python -m hola_ray.run --resume {out}",
        file=sys.stderr,
        flush=True,
    )
    ray.shutdown()
    return 130


def script() -> None:
    """`hola-run` (`[project.scripts]`): `main` under the fixed hash seed, as `python -m
    hola_ray.run` runs it (`hola_ray.process.fixed_hash_seed`)."""
    from hola_ray.process import fixed_hash_seed, leave, pause_collector

    fixed_hash_seed("hola_ray.commands.run", sys.argv[1:])
    pause_collector()
    from hola_ray.clock import process_start

    leave(main(started=process_start()))


if __name__ == "__main__":
    script()
