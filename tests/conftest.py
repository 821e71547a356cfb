"""Shared fixtures: the default scenario and a nearly frozen one for hand-worked geometry."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from hypothesis import settings

if TYPE_CHECKING:
    from hola_ray.env import PursuitConfig

# The commands re-run themselves under PYTHONHASHSEED=0 when it is not set
# (`hola_ray.process.fixed_hash_seed`): the tests' subprocesses start with it set, as
# the re-run would, and skip a second interpreter's imports (seconds each).
os.environ.setdefault("PYTHONHASHSEED", "0")
# The suite's two workers (pytest-xdist) share the 2 cores, and numba's parallel kernels
# on 2 OpenMP threads spin while another process holds the other core: the
# rollout tests took 17.7 s so, 6.3 s on one thread (4.9 s on two with a core idle). Every
# process of the suite (set before numba is imported, and inherited) runs them on one.
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
# torch's intra-op threads likewise (OpenMP, read when torch loads): each worker, command
# and Ray worker of the suite on one, as `hola_ray.process.pin_threads` puts a Ray worker
# on its one CPU.
os.environ.setdefault("OMP_NUM_THREADS", "1")
# torch inductor (the compiled loss's test) first probes which vector instruction sets the
# C++ compiler builds, one compile per set (seconds on a fresh machine); told that those
# the CPU reports build, it skips the probes and compiles the same kernels.
os.environ.setdefault("TORCHINDUCTOR_VEC_ISA_OK", "1")


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

    from hola_ray.process import worker_runtime_env
    from hola_ray.third_party import lean_local_ray

    lean_local_ray(log_monitor=False)  # as the commands', and nothing to stream to the driver
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


class Commands:
    """Commands (subprocesses) an end-to-end test starts: each in its own session, in the
    project's root, killed with its group (a local Ray included) when the test ends,
    whether it passed, failed or ran out of time (`pytest-timeout`)."""

    def __init__(self) -> None:
        self.processes: list[subprocess.Popen] = []

    def popen(self, args: list[str], **options) -> subprocess.Popen:
        options.setdefault("cwd", ROOT)
        process = subprocess.Popen(args, start_new_session=True, **options)
        self.processes.append(process)
        return process

    def stop(self) -> None:
        import signal

        for process in self.processes:
            if process.poll() is None:
                try:
                    os.killpg(process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            for pipe in (process.stdout, process.stderr):
                if pipe is not None:
                    pipe.close()
            process.wait()


@pytest.fixture()
def commands():
    """`commands.popen([...])`: a subprocess this test owns (`Commands`)."""
    started = Commands()
    yield started
    started.stop()


def smoke(commands: Commands, folder: Path) -> tuple[Path, subprocess.CompletedProcess]:
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
    process = commands.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = process.communicate(timeout=300)
    return out, subprocess.CompletedProcess(cmd, process.returncode, stdout, stderr)


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """`python -m hola_ray.run` on configs/smoke.yaml, made once for the whole session (the
    first worker to ask makes it, the others wait on its lock and read it): its run
    directory and the finished process. Tests read and copy the folder, never change it.
    Two of them: the run directory's contents, and the experiment's hola-s0 trial (same
    config and seed, run as a Ray task) matching it. It weighs its hyperedges on
    evaluation actors, where the smoke config plays them in the driver, so that match also
    shows the two Grapher paths give the same run."""
    import json

    from filelock import FileLock

    base = tmp_path_factory.getbasetemp()
    # one folder for every xdist worker of this session (a worker's basetemp is under the
    # session's); without xdist the session's own, never one an earlier session left
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    done = shared / "smoke.json"
    with FileLock(str(shared / "smoke.lock")):
        if not done.is_file():
            started = Commands()
            try:
                out, finished = smoke(started, shared)
            finally:
                started.stop()
            said = {"args": finished.args, "returncode": finished.returncode, "out": str(out)}
            said |= {"stdout": finished.stdout, "stderr": finished.stderr}
            done.write_text(json.dumps(said))
    said = json.loads(done.read_text())
    finished = subprocess.CompletedProcess(
        said["args"], said["returncode"], said["stdout"], said["stderr"]
    )
    return Path(said["out"]), finished


_WARM = """
import gc
gc.disable()  # a short process that only compiles: its collections would walk all it imported
import sys
import numba
import numpy as np
from hola_ray.env import _kernels
from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
c = PursuitConfig()
env = BatchedPursuit(c, 4)
mask = np.ones(4, dtype=bool)
if sys.argv[1] == "step":
    args = (np.zeros((4, c.n_pursuers)), env._kinematic, env._params, env._arena, env._out)
    _kernels.step_all.compile(tuple(numba.typeof(a) for a in args))
else:
    from hola_ray.policies.registry import make_policy  # torch: seconds, for this half only

    for kernel in (_kernels.reset_masked, _kernels.observe_all):
        args = (mask, env._params, env._arena, env.obs)
        kernel.compile(tuple(numba.typeof(a) for a in args))
    for name in ("greedy", "vicsek", "apf-a-0"):
        policy = make_policy(name, c)
        policy.reset()
        policy.act(np.zeros((4, env.layout.dim), dtype=np.float32))
"""
"""The simulator's numba kernels and the hand-written policies', compiled into numba's cache
by two processes at once (the step, the longer; the reset, the observation and the
policies), while the workers start: otherwise each worker and each Ray worker compiles
them all itself."""

_WARMING: list[subprocess.Popen] = []


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers", "e2e: drives the commands end to end in subprocesses (own timeout each)"
    )
    config.addinivalue_line("markers", "ray: the module starts a Ray of its own")
    controller = not hasattr(config, "workerinput")
    if controller and getattr(config.option, "numprocesses", None):
        for part in ("step", "reset"):  # while the workers start and collect
            _WARMING.append(subprocess.Popen([sys.executable, "-c", _WARM, part], cwd=ROOT))
    else:  # a process that collects: the test modules import torch, Ray and RLlib
        from hola_ray.process import pause_collector

        pause_collector(limit_s=600.0)  # until the collection is done, as a command's start


def pytest_collection_finish(session) -> None:
    """The collector on again once the tests are collected, what their imports made frozen:
    the collections while the tests run skip it (`hola_ray.process.resume_collector`)."""
    from hola_ray.process import resume_collector

    resume_collector()


_STARTS_RAY = {"ray_session", "smoke_run", "commands"}


def pytest_collection_modifyitems(session, config, items) -> None:
    """The modules that start commands (`e2e`) first, then those that start a Ray, then
    the rest, each group in collection order: the workers (`--dist loadfile`, no
    reordering by count) take the long modules first and end on short ones, so that
    neither waits long for the other at the end. A rule on what a module does, no list."""
    weight: dict[str, int] = {}
    for item in items:
        module = item.nodeid.split("::")[0]
        if item.get_closest_marker("e2e"):
            rank = 0
        elif item.get_closest_marker("ray") or _STARTS_RAY & set(item.fixturenames):
            rank = 1
        else:
            rank = 2
        weight[module] = min(weight.get(module, 2), rank)
    items.sort(key=lambda item: weight[item.nodeid.split("::")[0]])


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_node_collection_finished(node, ids) -> None:
    """No test starts before the kernels are in numba's cache."""
    while _WARMING:
        if _WARMING.pop().wait() != 0:
            raise RuntimeError("compiling the simulator's kernels failed (tests/conftest.py)")


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
    (`hola_ray.process.leave`)."""
    import gc

    gc.freeze()
