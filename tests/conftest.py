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
from typing import TYPE_CHECKING

import pytest
from hypothesis import settings

if TYPE_CHECKING:
    from hola_ray.env import PursuitConfig

# The commands re-run themselves under PYTHONHASHSEED=0 when it is not set
# (`hola_ray.progress.fixed_hash_seed`): the tests' subprocesses start with it set, as
# the re-run would, and skip a second interpreter's imports (seconds each).
os.environ.setdefault("PYTHONHASHSEED", "0")
# The suite shares its 2 cores with its background work (`Background`), and numba's
# parallel kernels on 2 OpenMP threads spin while another process holds the other core: the
# rollout tests took 17.7 s so, 6.3 s on one thread (4.9 s on two with a core idle). Every
# process of the suite (set before numba is imported, and inherited) runs them on one.
os.environ.setdefault("NUMBA_NUM_THREADS", "1")


@pytest.fixture(scope="session")
def config() -> PursuitConfig:
    from hola_ray.env import PursuitConfig

    return PursuitConfig()


@pytest.fixture(scope="session")
def frozen_config() -> PursuitConfig:
    """dt = 1e-6 s: drones move at most 6e-7 m per step, so set distances hold to 1e-6."""
    from hola_ray.env import PursuitConfig

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
    "tests/test_clock.py",
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


class Background:
    """Work that only drives commands (subprocesses) and reads their files, started once
    the tests are collected and run one job after another in a thread. Most of the suite
    plays in this one process and leaves a core idle much of the time (Ray modules too: half
    their time); the background takes it. A test marked
    `@pytest.mark.background.with_args(job)` gets the job's result (or its error) from the
    fixture: `background(job)`. The jobs of the selected tests run in the order the tests
    were collected, after the kernels are compiled (`_WARM`) and the smoke run (`smoke_run`)
    made. A job is called as `job(background, folder)`: it starts its commands with
    `background.popen`, so that a session that stops kills them, and may take an earlier
    job's result."""

    def __init__(self, jobs: list) -> None:
        import concurrent.futures

        self.root = Path(tempfile.mkdtemp(prefix="hola_ray-background-"))
        self.processes: list[subprocess.Popen] = []
        self.lock = threading.Lock()
        self.ended = False
        self.pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="background")
        self.futures = {job: self.pool.submit(self._run, job) for job in jobs}

    def _run(self, job):
        folder = self.root / job.__name__
        folder.mkdir()
        return job(self, folder)

    def __call__(self, job):
        """The result of `job` (a job function, or its name), once it ended."""
        if isinstance(job, str):
            [job] = [j for j in self.futures if j.__name__ == job]
        return self.futures[job].result()

    def popen(self, args: list[str], **options) -> subprocess.Popen:
        """`subprocess.Popen` in its own session (a kill takes its local Ray with it), in the
        project's root; refused once the session ended."""
        with self.lock:
            if self.ended:
                raise RuntimeError("the test session ended")
            options.setdefault("cwd", ROOT)
            process = subprocess.Popen(args, start_new_session=True, **options)
            self.processes.append(process)
            return process

    def stop(self) -> None:
        import signal

        with self.lock:
            self.ended = True
        self.pool.shutdown(wait=False, cancel_futures=True)
        for process in self.processes:
            if process.poll() is None:  # the session stopped before it ended
                try:
                    os.killpg(process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        self.pool.shutdown(wait=True)
        shutil.rmtree(self.root, ignore_errors=True)


_BACKGROUND: list[Background] = []


def warm_kernels(background: Background, folder: Path) -> int:
    with open(folder / "log", "w") as log:
        warm = background.popen([sys.executable, "-c", _WARM], stdout=log, stderr=log)
    return warm.wait()


def smoke(background: Background, folder: Path) -> tuple[Path, subprocess.CompletedProcess]:
    """`python -m hola_ray.run` on configs/smoke.yaml: its run directory and the finished
    process."""
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
    process = background.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = process.communicate(timeout=600)
    return out, subprocess.CompletedProcess(cmd, process.returncode, stdout, stderr)


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers", "background(job): job(background, folder) runs in the background (`Background`)"
    )


def pytest_collection_modifyitems(session, config, items) -> None:
    def steps_no_simulator(item) -> bool:
        path = item.path.relative_to(ROOT).as_posix()
        return path.startswith(NO_SIMULATOR)

    items.sort(key=lambda item: not steps_no_simulator(item))  # stable: otherwise as found


def pytest_collection_finish(session) -> None:
    jobs: list = []
    for item in session.items:
        if "smoke_run" in getattr(item, "fixturenames", ()) and smoke not in jobs:
            jobs.append(smoke)
        for mark in item.iter_markers("background"):
            if mark.args[0] not in jobs:
                jobs.append(mark.args[0])
    if jobs:
        jobs.sort(key=lambda job: job is not smoke)  # first: other jobs may take it
        _BACKGROUND.append(Background([warm_kernels, *jobs]))


def pytest_sessionfinish(session) -> None:
    while _BACKGROUND:
        _BACKGROUND.pop().stop()


@pytest.fixture(scope="session")
def background() -> Background:
    """`background(job)`: the result of a job a marked test asked for (`Background`)."""
    return _BACKGROUND[0]


@pytest.fixture(scope="session")
def smoke_run() -> tuple[Path, subprocess.CompletedProcess]:
    """`python -m hola_ray.run` on configs/smoke.yaml, once per session, made in the
    background (`Background`): its run directory and the finished process. Tests read and
    copy the folder, never change it. Two of them: the run directory's contents, and the
    experiment's hola-s0 trial (same config and seed, run as a Ray task) matching it. It
    weighs its hyperedges on member actors, where the smoke config plays them in the
    driver, so that match also shows the two Grapher paths give the same run."""
    return _BACKGROUND[0](smoke)


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
