"""How much of a run's time is learning: the default run, timed as a whole process, against
its Oracle alone beside partners, measured in one sitting.

    python benchmarks/run_speed.py [--repeats 2] [--before COMMIT] [--out DIR]
                                   [--set section.field=value ...]

For each repeat, and for each code version (the commit `--before` names, checked out in a
git worktree, then this tree, interleaved), it times `python -m hola_ray.run --out DIR`
(the embedded default, or it with `--set`s) from launch to exit, and reads the learner
transitions it trained from its metrics.csv; then the same version's Oracle alone, seated
beside partners as the run's is (`benchmarks/oracle_speed.py --seatings partners`, the
run's per-generation budget of learner transitions after a warm-up iteration). The ratio
(learner transitions per wall-second of the whole run ÷ the Oracle's own rate) says how
much of the run's time goes to learning. Each version first plays the smoke config once,
so numba's kernels are compiled before anything is timed. `benchmarks/calib.py` runs before
and after; prints one JSON line per measurement and a summary line last.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
T975 = (float("nan"), 12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262)


def joining() -> dict[str, str]:
    """The commands' environment: where this process holds a Ray (the test suite's), they
    join it as they would a cluster (RAY_ADDRESS) instead of each starting their own."""
    import ray

    env = dict(os.environ)
    if ray.is_initialized():
        env["RAY_ADDRESS"] = ray.get_runtime_context().gcs_address
    return env


def calibrate(best_of: int = 5, fraction: float = 1.0) -> float:
    command = [sys.executable, str(ROOT / "benchmarks" / "calib.py"), "--best-of", str(best_of)]
    out = subprocess.run(
        command + ["--fraction", str(fraction)],
        capture_output=True,
        text=True,
        check=True,
    )
    return float(json.loads(out.stdout.strip().splitlines()[-1])["scale"])


def whole_run(tree: Path, out: Path, sets: list[str], config: Path | None = None) -> dict:
    """`python -m hola_ray.run` of `tree`'s code, from launch to exit."""
    command = [sys.executable, "-m", "hola_ray.run", "--out", str(out), "--quiet"]
    if config is not None:
        command += ["--config", str(config)]
    for s in sets:
        command += ["--set", s]
    start = time.perf_counter()
    done = subprocess.run(command, cwd=tree, capture_output=True, text=True, env=joining())
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"the run failed in {tree}:\n{done.stderr[-3000:]}")
    rows = list(csv.DictReader((out / "metrics.csv").open()))
    samples = int(float(rows[-1]["learner_samples"]))
    return {"wall_s": round(wall, 1), "learner_samples": samples, "per_s": samples / wall}


def oracle_alone(tree: Path, samples: int, sets: list[str], config: Path | None = None) -> float:
    """The Oracle beside partners, learner transitions per second (`oracle_speed.py`)."""
    command = [
        sys.executable,
        str(tree / "benchmarks" / "oracle_speed.py"),
        "--seatings",
        "partners",
        "--samples",
        str(samples),
        "--repeats",
        "1",
        "--against",
        "oracle.overlap=true,true",
    ]
    if config is not None:
        command += ["--config", str(config)]
    for s in sets:
        command += ["--set", s]
    # the tree's own package, not the one installed in the venv (a script's folder, not
    # its working directory, heads sys.path)
    env = {**joining(), "PYTHONPATH": str(tree)}
    done = subprocess.run(command, cwd=tree, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"oracle_speed failed in {tree}:\n{done.stderr[-3000:]}")
    rows = [json.loads(x) for x in done.stdout.splitlines() if '"learner_samples_per_s"' in x]
    return statistics.mean(r["learner_samples_per_s"] for r in rows)


def warm(tree: Path, scratch: Path) -> None:
    """Compile the version's numba kernels (a smoke run), so no measurement pays for it."""
    out = scratch / f"warm-{tree.name}"
    subprocess.run(
        [sys.executable, "-m", "hola_ray.run", "--config", "configs/smoke.yaml"]
        + ["--out", str(out), "--quiet", "--no-dashboard"],
        cwd=tree,
        capture_output=True,
        check=True,
    )


def interval(values: list[float]) -> list[float]:
    n = len(values)
    if n < 2:
        return [values[0], values[0]]
    half = T975[min(n - 1, len(T975) - 1)] * statistics.stdev(values) / n**0.5
    return [round(statistics.mean(values) - half, 3), round(statistics.mean(values) + half, 3)]


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--before", help="a commit to measure beside this tree, interleaved")
    parser.add_argument("--samples", type=int, default=100_000, help="the Oracle alone's budget")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    parser.add_argument("--out", type=Path, help="where the runs go (default: a temp folder)")
    parser.add_argument("--config", type=Path, help="a run config (default: the embedded one)")
    parser.add_argument("--no-warm", action="store_true", help="no smoke run first")
    parser.add_argument("--calib-best-of", type=int, default=5, help="calib.py's --best-of")
    parser.add_argument("--calib-fraction", type=float, default=1.0, help="calib.py's --fraction")
    args = parser.parse_args(argv)
    scratch = args.out or Path(tempfile.mkdtemp(prefix="run_speed-"))
    scratch.mkdir(parents=True, exist_ok=True)
    trees = {"after": ROOT}
    if args.before:
        before = scratch / "before"
        if not before.exists():
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(before), args.before],
                cwd=ROOT,
                check=True,
                capture_output=True,
            )
        trees = {"before": before, "after": ROOT}
    scales = [calibrate(args.calib_best_of, args.calib_fraction)]
    for tree in trees.values() if not args.no_warm else ():
        warm(tree, scratch)
    rows = []
    for repeat in range(args.repeats):
        for label, tree in trees.items():
            run = whole_run(tree, scratch / f"{label}-{repeat}", args.sets, args.config)
            alone = oracle_alone(tree, args.samples, args.sets, args.config)
            rows.append(
                {
                    "code": label,
                    "repeat": repeat,
                    **run,
                    "oracle_alone_per_s": round(alone, 1),
                    "ratio": round(run["per_s"] / alone, 3),
                }
            )
            print(json.dumps(rows[-1]), flush=True)
    scales.append(calibrate(args.calib_best_of, args.calib_fraction))
    summary: dict = {"repeats": args.repeats, "sets": args.sets, "calib_scale": scales}
    for label in trees:
        mine = [r for r in rows if r["code"] == label]
        ratios = [r["ratio"] for r in mine]
        summary[label] = {
            "ratio": round(statistics.mean(ratios), 3),
            "ratio_95": interval(ratios),
            "wall_s": [r["wall_s"] for r in mine],
            "reference_s": [round(r["wall_s"] * statistics.mean(scales), 1) for r in mine],
        }
    if args.before:
        speedups = [
            b["wall_s"] / a["wall_s"]
            for b, a in zip(
                [r for r in rows if r["code"] == "before"],
                [r for r in rows if r["code"] == "after"],
                strict=True,
            )
        ]
        summary["before_wall_over_after"] = {
            "mean": round(statistics.mean(speedups), 2),
            "95": interval(speedups),
        }
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
