"""Shared fixtures: the default scenario and a nearly frozen one for hand-worked geometry."""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import pytest
from hypothesis import settings

from hola_ray.env import PursuitConfig

# The commands re-run themselves under PYTHONHASHSEED=0 when it is not set
# (`hola_ray.progress.fixed_hash_seed`): the tests' subprocesses start with it set, as
# the re-run would, and skip a second interpreter's imports (seconds each).
os.environ.setdefault("PYTHONHASHSEED", "0")


@pytest.fixture(scope="session")
def config() -> PursuitConfig:
    return PursuitConfig()


@pytest.fixture(scope="session")
def frozen_config() -> PursuitConfig:
    """dt = 1e-6 s: drones move at most 6e-7 m per step, so set distances hold to 1e-6."""
    return dataclasses.replace(PursuitConfig(), dt=1e-6)


# Property tests draw the same examples on every run, so a statistical check (the
# sampler's 4-standard-error bound) cannot flake in CI.
settings.register_profile("repeatable", derandomize=True)
settings.load_profile("repeatable")


@pytest.fixture(scope="module")
def ray_session():
    """One local Ray per test module (start-up and per-actor torch imports cost seconds)."""
    import ray

    from hola_ray.progress import worker_runtime_env

    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        namespace="hola_ray_tests",
        log_to_driver=False,
        runtime_env=worker_runtime_env(),  # as the commands: workers share the hash seed
    )
    yield ray
    ray.shutdown()


ROOT = Path(__file__).resolve().parent.parent


# Modules whose tests step no simulator (measured: none of them writes a numba cache file).
# They run first, while the background compiles the simulator's kernels into numba's cache
# (about 25 s in a fresh clone; `_WARM`) for every later test and worker. A module missing
# here only runs later; one wrongly listed compiles the kernels itself: no result changes.
NO_SIMULATOR = (
    "tests/test_layers.py",
    "tests/test_progress.py",
    "tests/test_interrupt.py",
    "tests/test_cli_errors.py",
    "tests/test_scripts.py",
    "tests/env/test_config.py",
    "tests/hypergraph/",
    "tests/evaluation/test_compare.py",
    "tests/methods/test_run_config.py",
    "tests/methods/test_methods.py",
    "tests/oracle/test_minibatches.py",
    "tests/oracle/test_ppo_settings.py",
    "tests/oracle/test_rllib_fixes.py",
    "tests/population/test_lock.py",
    "tests/population/test_state.py",
)

_WARM = (
    "from hola_ray.env.config import PursuitConfig\n"
    "from hola_ray.evaluation.rollout import rollout\n"
    "from hola_ray.policies.registry import make_policy\n"
    "c = PursuitConfig()\n"
    "rollout(c, [make_policy(n, c) for n in ('greedy', 'vicsek', 'apf-a-0')], 2)\n"
)
"""Every numba kernel of the simulator and the hand-written policies, compiled and cached."""

_SMOKE: dict[str, object] = {}
"""The background work: its folder, the warm-up, then the smoke run (`smoke_run`)."""
_BACKGROUND = threading.Lock()


def pytest_collection_modifyitems(session, config, items) -> None:
    def steps_no_simulator(item) -> bool:
        path = item.path.relative_to(ROOT).as_posix()
        return path.startswith(NO_SIMULATOR)

    items.sort(key=lambda item: not steps_no_simulator(item))  # stable: otherwise as found


def pytest_collection_finish(session) -> None:
    """When a selected test asks for `smoke_run`, start the background work now: the kernels
    compiled (`_WARM`), then the smoke run. The suite's first modules play in this one
    process and leave a core idle, which the background takes instead of making the first
    tests wait for it."""
    if not any("smoke_run" in getattr(item, "fixturenames", ()) for item in session.items):
        return
    folder = Path(tempfile.mkdtemp(prefix="hola_ray-smoke-"))
    out = folder / "smoke"
    cmd = [
        sys.executable,
        "-m",
        "hola_ray.run",
        "--config",
        str(ROOT / "configs" / "smoke.yaml"),
        "--out",
        str(out),
        "--set",
        "grapher.workers=2",
        "--no-dashboard",
        "--quiet",
    ]
    _SMOKE.update(folder=folder, out=out, cmd=cmd)

    def start(name: str, args: list[str], log: str):
        """A background process, unless the session already ended (then None)."""
        with (
            _BACKGROUND,
            open(folder / f"{log}.out", "w") as out,
            open(folder / f"{log}.err", "w") as err,
        ):
            if not _SMOKE.get("ended"):
                _SMOKE[name] = subprocess.Popen(args, stdout=out, stderr=err, text=True, cwd=ROOT)
            return _SMOKE.get(name)

    def background() -> None:
        warm = start("warm", [sys.executable, "-c", _WARM], "warm")
        if warm is not None:
            warm.wait()
            start("process", cmd, "smoke")

    _SMOKE["thread"] = threading.Thread(target=background, daemon=True)
    _SMOKE["thread"].start()


def pytest_sessionfinish(session) -> None:
    if "thread" not in _SMOKE:
        return
    with _BACKGROUND:
        _SMOKE["ended"] = True  # nothing more starts
    for name in ("warm", "process"):
        process = _SMOKE.get(name)
        if process is not None and process.poll() is None:  # the session stopped first
            process.kill()
            process.wait()
    _SMOKE["thread"].join()
    shutil.rmtree(_SMOKE["folder"], ignore_errors=True)


@pytest.fixture(scope="session")
def smoke_run() -> tuple[Path, subprocess.CompletedProcess]:
    """`python -m hola_ray.run` on configs/smoke.yaml, once per session (started in the
    background once the tests were collected): its run directory and the finished process.
    Tests read and copy the folder, never change it. Two of them: the run directory's
    contents, and the experiment's hola-s0 trial (same config and seed, run as a Ray task)
    matching it. It weighs its hyperedges on member actors, where the smoke config plays
    them in the driver, so that match also shows the two Grapher paths give the same run."""
    _SMOKE["thread"].join()
    process = _SMOKE["process"]
    process.wait(timeout=600)
    folder = _SMOKE["folder"]
    done = subprocess.CompletedProcess(
        _SMOKE["cmd"],
        process.returncode,
        (folder / "smoke.out").read_text(),
        (folder / "smoke.err").read_text(),
    )
    return _SMOKE["out"], done


class _Straight:
    """A pursuer that never turns (action 0.5): it flies on until it meets a wall."""

    name = "straight"

    def reset(self, mask=None):
        pass

    def act(self, obs):
        import numpy as np

        return np.full(len(obs), 0.5)


@pytest.fixture()
def straight():
    """A pursuer policy that crashes in nearly every episode, in its own seat."""
    return _Straight()


@pytest.fixture
def local_learner():
    """`local_learner(algo)`: an RLlib algorithm's local Learner, through the public
    `LearnerGroup.foreach_learner` (not its private `_learner`)."""

    def get(algo):
        (result,) = algo.learner_group.foreach_learner(lambda learner: learner)
        return result.get()

    return get


def pytest_unconfigure(config) -> None:
    """Freeze every live object before the interpreter ends: its last collection would walk
    all that torch, RLlib and Ray made (seconds), as at a command's end
    (`hola_ray.progress.leave`)."""
    import gc

    gc.freeze()
