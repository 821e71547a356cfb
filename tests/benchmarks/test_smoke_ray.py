"""The benchmarks that build an Oracle or start a run (Ray and RLlib) run to their end on the
smoke config's sizes, through their `main` in this process (each joins the module's Ray, as
it would a notebook's), and end on their figures as JSON. Their figures mean nothing at
these sizes: the test is that every part of each script still runs against the package."""

from __future__ import annotations

import importlib.util
import inspect
import json
import sys

import pytest

from hola_ray.homes import ROOT

pytestmark = pytest.mark.usefixtures("ray_session")  # one Ray, which the scripts join

BENCHMARKS = ROOT / "benchmarks"
SMOKE = str(ROOT / "configs" / "smoke.yaml")

RAY_SMOKE = {
    "oracle_speed.py": (
        ["--config", SMOKE, "--samples", "300", "--repeats", "1", "--seatings", "partners"],
        '"ratio"',
    ),
    "update_step.py": (
        ["--config", SMOKE, "--repeats", "1", "--paths", "module,eager"],
        "loss_differences_from_module",
    ),
    "profile_sampling.py": (
        ["--config", SMOKE, "--set", "oracle.env_runners=1", "--steps", "300"]
        + ["--sampler", "batched", "--top", "3"],
        "under cProfile",
    ),
    "service_speed.py": (["--smoke"], "batched env runner / PettingZoo path"),
    "run_speed.py": (
        ["--config", SMOKE, "--repeats", "1", "--samples", "300", "--no-warm"]
        + ["--calib-best-of", "1", "--calib-fraction", "0.02"]
        # the run and the Oracle alone smaller still: a quarter of the smoke config's steps
        # and episodes (the script's parts are what is tested, not its figures)
        + ["--set", "pretrain.env_steps=500", "--set", "oracle.env_steps=500"]
        + ["--set", "oracle.train_batch=250", "--set", "oracle.minibatch=125"]
        + ["--set", "validation.episodes=3", "--set", "grapher.episodes_per_edge=1"],
        '"oracle_alone_per_s"',
    ),
}
"""script → (its arguments at the smoke config's sizes, a piece of what it must print)"""


def _run(name: str, argv: list[str], monkeypatch, capsys) -> str:
    # imported by its own name from benchmarks/, as `python benchmarks/NAME` would: the
    # processes a script spawns (service_speed's scaling probe) import it again by name
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.delitem(sys.modules, name[:-3], raising=False)
    module = importlib.import_module(name[:-3])
    # what it sends to Ray's workers goes by value, as from a script's __main__
    from ray import cloudpickle

    cloudpickle.register_pickle_by_value(module)
    try:
        return _main(module.main, name, argv, monkeypatch, capsys)
    finally:
        cloudpickle.unregister_pickle_by_value(module)


def _main(main, name: str, argv: list[str], monkeypatch, capsys) -> str:
    if inspect.signature(main).parameters:
        main(argv)
    else:  # reads sys.argv itself
        monkeypatch.setattr(sys, "argv", [name, *argv])
        main()
    out = capsys.readouterr().out
    json.loads(out.strip().splitlines()[-1])  # every one ends with its figures as JSON
    return out


@pytest.mark.parametrize("name", sorted(RAY_SMOKE))
def test_a_ray_bound_benchmark_runs_to_its_end_on_the_smoke_config(name, monkeypatch, capsys):
    argv, printed = RAY_SMOKE[name]
    out = _run(name, argv, monkeypatch, capsys)
    assert printed in out, out[-2000:]


def test_the_learning_curves_of_a_finished_run(smoke_run, tmp_path, monkeypatch, capsys):
    """learning.py on the session's smoke run (its learner as three copies, per generation),
    no training of its own."""
    run_dir, finished = smoke_run
    assert finished.returncode == 0, finished.stderr[-3000:]
    argv = ["--sp-run", str(run_dir), "--skip-default", "--episodes", "2", "--out", str(tmp_path)]
    out = _run("learning.py", argv, monkeypatch, capsys)
    assert "sp gen 1" in out, out[-2000:]
    assert (tmp_path / "learning.png").is_file() and (tmp_path / "learning.json").is_file()
