"""Publish an experiment as it goes: each finished trial's figures and chosen learner, then
the results, copied into a folder of the repository and committed there.

    python -m hola_ray.experiment.publish RUN_DIR DOCS_DIR [--commit] [--watch SECONDS]

A trial is copied once `progress.json` says it is done: its `config.yaml` (which names its
population build), `metrics.csv`, `best.json`, `best.pt` (about 26 kB: anyone can play the
compared learner) and `learner.json`; each learner's evaluation (`evaluation/TRIAL.json`) as
it is played; then, once written, the experiment's `experiment.yaml`,
`results.json`, `results.md` and `figure.png` (the open-team grid's `open-teams-<arena>.png`
in its place). The open-team grid's cells are copied as they are played
(`evaluation/open-teams/`), and restored with the trials. `--commit` commits each new trial on
its own (`git commit` in the repository that holds DOCS_DIR), so a machine replaced mid-experiment
loses at most the trials in progress; `--watch` polls until the results are written (and,
started beside a new experiment, until it has written its folder).

    python -m hola_ray.experiment.publish RUN_DIR DOCS_DIR --restore

goes the other way, on a new machine: the published experiment and its done trials copied
back into RUN_DIR (each trial marked done, `tasks.RESTORED`), so that `python -m
hola_ray.experiment --resume RUN_DIR` trains only the trials not yet published and
evaluates them all from their `best.pt`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import time
from pathlib import Path

TRIAL_FILES = ("config.yaml", "metrics.csv", "best.json", "best.pt", "learner.json")
RESULT_FILES = ("experiment.yaml", "results.json", "results.md", "figure.png")
CELLS = "open-teams"  # the open-team grid's cells, kept as played under evaluation/


def done_trials(run: Path) -> list[str]:
    path = run / "progress.json"
    if not path.is_file():
        return []
    rows = json.loads(path.read_text())
    return sorted(t for t, row in rows.items() if row.get("status") == "done")


def finished(run: Path, docs: Path) -> bool:
    """Nothing more to come: the results are published, or for an experiment without an
    evaluation (a pilot) every trial is done."""
    import yaml

    if (docs / "results.json").is_file():
        return True
    rows = (
        json.loads((run / "progress.json").read_text()) if (run / "progress.json").is_file() else {}
    )
    pilot = yaml.safe_load((run / "experiment.yaml").read_text()).get("evaluation") == "none"
    return pilot and bool(rows) and len(done_trials(run)) == len(rows)


def publish(run: Path, docs: Path) -> list[str]:
    """Copy what is new: the trials done since the last call, and the results once they
    are complete. Returns what was copied (trial names, `results`)."""
    copied = []
    docs.mkdir(parents=True, exist_ok=True)
    if not (docs / "experiment.yaml").is_file():
        shutil.copyfile(run / "experiment.yaml", docs / "experiment.yaml")
    for trial in done_trials(run):
        target = docs / "trials" / trial
        if (target / "best.pt").is_file():
            continue
        target.mkdir(parents=True, exist_ok=True)
        for name in TRIAL_FILES:
            source = run / "trials" / trial / name
            if source.is_file():
                shutil.copyfile(source, target / name)
        copied.append(trial)
    for figures in sorted((run / "evaluation").glob("*.json")):  # each learner's, as played
        target = docs / "evaluation" / figures.name
        if not target.is_file() or target.read_bytes() != figures.read_bytes():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(figures, target)
            copied.append(f"evaluation of {figures.stem}")
    cells = publish_cells(run / "evaluation" / CELLS, docs / "evaluation" / CELLS)
    if cells:
        copied.append(f"{cells} open-team cell(s)")
    results = run / "results.json"
    if results.is_file() and (
        not (docs / "results.json").is_file()
        or (docs / "results.json").read_bytes() != results.read_bytes()
    ):
        for name in RESULT_FILES:
            if (run / name).is_file():
                shutil.copyfile(run / name, docs / name)
        for figure in sorted(run.glob("open-teams-*.png")):  # the open-team grid's, per arena
            shutil.copyfile(figure, docs / figure.name)
        copied.append("results")
    return copied


def publish_cells(kept: Path, target: Path) -> int:
    """Copy the open-team grid's cells played since the last call (each cell's episodes, then
    its row, which the grid looks for), so a grid that spans machines plays each cell once.
    Returns how many were copied."""
    copied = 0
    for row in sorted(kept.glob("*.json")) if kept.is_dir() else []:
        episodes = row.with_suffix(".npz")
        done = target / row.name
        if not episodes.is_file() or done.is_file() and done.read_bytes() == row.read_bytes():
            continue
        target.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(episodes, target / episodes.name)
        shutil.copyfile(row, done)
        copied += 1
    return copied


def restore(docs: Path, run: Path) -> list[str]:
    """Copy the published experiment in `docs` back into the experiment directory `run`:
    its `experiment.yaml` (or check that `run`'s is the same), and each published trial not
    done in `run`, marked done at the last generation its metrics.csv holds. Returns the
    trials restored."""
    import csv

    from hola_ray.experiment.tasks import RESTORED

    config = docs / "experiment.yaml"
    if not config.is_file():
        raise SystemExit(f"{docs} holds no published experiment (no experiment.yaml)")
    run.mkdir(parents=True, exist_ok=True)
    if not (run / "experiment.yaml").is_file():
        shutil.copyfile(config, run / "experiment.yaml")
    elif (run / "experiment.yaml").read_bytes() != config.read_bytes():
        raise SystemExit(f"{run}/experiment.yaml is not the one published in {docs}")
    restored, done = [], set(done_trials(run))
    for folder in sorted((docs / "trials").glob("*/")):
        if not (folder / "best.pt").is_file() or not (folder / "metrics.csv").is_file():
            continue
        trial = run / "trials" / folder.name
        if trial.is_dir():
            if (trial / RESTORED).is_file() or folder.name in done:
                continue
            shutil.rmtree(trial)  # a partial copy here is behind the published, done trial
        trial.mkdir(parents=True)
        for name in TRIAL_FILES:
            if (folder / name).is_file():
                shutil.copyfile(folder / name, trial / name)
        with (folder / "metrics.csv").open() as f:
            last = max(int(float(row["generation"])) for row in csv.DictReader(f))
        (trial / RESTORED).write_text(json.dumps({"from": str(folder), "generation": last}))
        restored.append(folder.name)
    for figures in sorted((docs / "evaluation").glob("*.json")):  # learners already played
        target = run / "evaluation" / figures.name
        if not target.is_file():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(figures, target)
    publish_cells(docs / "evaluation" / CELLS, run / "evaluation" / CELLS)  # cells played
    return restored


def commit(docs: Path, what: list[str]) -> bool:
    """`git add DOCS && git commit` in DOCS's repository; False when git refused (another
    commit in progress: the next poll tries again)."""
    git = ["git", "-C", str(docs)]
    add = subprocess.run([*git, "add", "."], capture_output=True, text=True)
    message = f"{docs.name}: {', '.join(what)} published (hola_ray.experiment.publish)"
    done = subprocess.run([*git, "commit", "-q", "-m", message, "--", "."], capture_output=True)
    return add.returncode == 0 and done.returncode == 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hola_ray.experiment.publish", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("run", type=Path, help="the experiment directory")
    parser.add_argument("docs", type=Path, help="where in the repository to copy it")
    parser.add_argument("--commit", action="store_true", help="commit each new trial")
    parser.add_argument("--watch", type=float, metavar="SECONDS", help="poll until results")
    parser.add_argument(
        "--restore",
        action="store_true",
        help="the other way: the published trials back into RUN_DIR, to --resume there",
    )
    args = parser.parse_args(argv)
    if args.restore:
        done = restore(args.docs, args.run)
        print(
            f"restored {len(done)} published trial(s) into {args.run}: {', '.join(done) or '-'}; "
            f"continue with: python -m hola_ray.experiment --resume {args.run}",
            flush=True,
        )
        return 0
    if not (args.run / "experiment.yaml").is_file():
        if args.watch is None:
            parser.error(f"{args.run} holds no experiment.yaml")
        # started beside the experiment, before it wrote its folder: wait for it
        print(f"waiting for {args.run / 'experiment.yaml'} (written as the experiment starts)")
        while not (args.run / "experiment.yaml").is_file():
            time.sleep(args.watch)
    args.docs.mkdir(parents=True, exist_ok=True)
    pending: list[str] = []
    while True:
        pending += publish(args.run, args.docs)
        if pending:
            print(f"published {', '.join(pending)} in {args.docs}", flush=True)
            if not args.commit or commit(args.docs, pending):
                pending = []
        if args.watch is None or finished(args.run, args.docs) and not pending:
            return 0
        time.sleep(args.watch)


if __name__ == "__main__":
    raise SystemExit(main())
