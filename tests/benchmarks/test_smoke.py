"""Every script in benchmarks/ runs to its end on tiny sizes, so that a rename in the package
cannot break one silently (service_speed.py once stopped on a renamed metrics column and
nothing noticed). Each runs in this process through its `main`, with the arguments below,
and must print its figures; the ones with a test of their own are named beside it."""

from __future__ import annotations

import importlib.util
import inspect
import json
import sys

import pytest

from hola_ray.homes import ROOT

BENCHMARKS = ROOT / "benchmarks"
LEARNER = ROOT / "results" / "competence-3v2" / "hola" / "trials" / "hola-s2"
"""a committed 3 vs 2 learner (its run folder holds best.pt)"""

SMOKE = {
    "myerson.py": ([], "max |diff|"),
    "calib.py": (["--best-of", "1", "--fraction", "0.02"], '"scale"'),
    "env_speed.py": (["--seconds", "0.02"], "batched core B=4096"),
    "guard_choice.py": (["1", str(LEARNER), "--horizon", "30"], '"validation"'),
    "seated.py": (
        [str(LEARNER / "best.pt"), "--teammates", "greedy", "vicsek", "--episodes", "2"],
        "its own seat crashed",
    ),
    "flight_training.py": (
        ["1", str(LEARNER.parent / "hola-s1"), str(LEARNER), "--horizon", "30"],
        "response - kinematic",
    ),
    "flight_gap.py": (
        [f"{LEARNER}:best", "--episodes", "1", "--horizon", "30"],
        "+ Greedy, VICSEK",
    ),
}
"""script → (its arguments at tiny sizes, a piece of what it must print)"""

TESTED_ELSEWHERE = {
    "cost_model.py": "tests/benchmarks/test_cost_model.py",
    "crashes.py": "tests/benchmarks/test_crashes.py",
    "movement.py": "tests/benchmarks/test_movement.py",
    "time_to_competence.py": "tests/benchmarks/test_time_to_competence.py",
}
RAY_BOUND = "tests/benchmarks/test_smoke_ray.py"
"""where the Ray- and RLlib-bound ones run on the smoke config's sizes"""


def test_every_benchmark_is_accounted_for():
    scripts = {p.name for p in BENCHMARKS.glob("*.py")}
    spec = importlib.util.spec_from_file_location("smoke_ray", ROOT / RAY_BOUND)
    ray_bound = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ray_bound)
    covered = set(SMOKE) | set(TESTED_ELSEWHERE) | set(ray_bound.RAY_SMOKE) | {"learning.py"}
    assert "test_the_learning_curves_of_a_finished_run" in vars(ray_bound)  # learning.py
    assert scripts == covered, {"new": scripts - covered, "gone": covered - scripts}
    for test in TESTED_ELSEWHERE.values():
        assert (ROOT / test).is_file(), test


def _module(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name[:-3]}", BENCHMARKS / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", sorted(SMOKE))
def test_a_benchmark_runs_to_its_end_on_tiny_sizes(name, monkeypatch, capsys):
    argv, printed = SMOKE[name]
    main = _module(name).main
    if inspect.signature(main).parameters:
        code = main(argv)
    else:  # reads sys.argv itself
        monkeypatch.setattr(sys, "argv", [name, *argv])
        code = main()
    assert code in (None, 0)
    out = capsys.readouterr().out
    assert printed in out, out[-2000:]
    last = out.strip().splitlines()[-1]
    assert isinstance(json.loads(last), dict | list)  # every one ends with its figures as JSON
