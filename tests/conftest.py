"""Shared fixtures: the default scenario and a nearly frozen one for hand-worked geometry."""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
import tempfile
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


_SMOKE: dict[str, object] = {}
"""The smoke run started in the background: its folder and process (`smoke_run`)."""


def pytest_collection_finish(session) -> None:
    """When a selected test asks for `smoke_run`, start it now, in the background: the
    suite's first modules play in this one process and leave a core idle, which the run
    takes instead of making its first test wait for it."""
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
    with open(folder / "stdout", "w") as stdout, open(folder / "stderr", "w") as stderr:
        process = subprocess.Popen(cmd, stdout=stdout, stderr=stderr, text=True, cwd=ROOT)
    _SMOKE.update(folder=folder, out=out, cmd=cmd, process=process)


def pytest_sessionfinish(session) -> None:
    process = _SMOKE.get("process")
    if process is not None:
        if process.poll() is None:  # the session stopped before it ended
            process.kill()
            process.wait()
        shutil.rmtree(_SMOKE["folder"], ignore_errors=True)


@pytest.fixture(scope="session")
def smoke_run() -> tuple[Path, subprocess.CompletedProcess]:
    """`python -m hola_ray.run` on configs/smoke.yaml, once per session (started when the
    tests were collected): its run directory and the finished process. Tests read and copy
    the folder, never change it. Two of them: the run directory's contents, and the
    experiment's hola-s0 trial (same config and seed, run as a Ray task) matching it.
    It weighs its hyperedges on member actors, where the smoke config plays them in the
    driver, so that match also shows the two Grapher paths give the same run."""
    process = _SMOKE["process"]
    process.wait(timeout=600)
    folder = _SMOKE["folder"]
    done = subprocess.CompletedProcess(
        _SMOKE["cmd"],
        process.returncode,
        (folder / "stdout").read_text(),
        (folder / "stderr").read_text(),
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
