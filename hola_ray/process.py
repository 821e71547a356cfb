"""A command's process: Ray's start (local or a cluster's), the fixed hash seed, torch's
threads and seed, quiet loggers, and the exit. Apart from the progress bar
(`hola_ray.progress`), which only draws."""

from __future__ import annotations

import sys
from types import ModuleType
from typing import Any, NoReturn

from hola_ray.third_party import lean_local_ray

NOISY_LOGGERS = (
    "ray._common.deprecation",  # RLlib's own RLModuleConfig deprecation, once per env runner
    "ray.rllib.algorithms.algorithm_config",  # "You are running PPO on the new API stack!"
    "ray.tune.utils.util",  # "Install gputil for GPU system monitoring."
)
"""Loggers whose warnings say nothing a user of this project can act on."""

RAY_RUNTIME_ENV = {
    "worker_process_setup_hook": "hola_ray.process.quiet_ray_noise",
    "env_vars": {"PYTHONHASHSEED": "0"},
}
"""`ray.init(runtime_env=...)`: every Ray worker of a run silences the same loggers and
iterates sets of strings in one order (see `fixed_hash_seed`)."""


NAMESPACE = "hola_ray"
"""The Ray namespace of this project's named actors (coordinators, mirrors)."""


def worker_runtime_env(local: bool = True) -> dict[str, Any] | None:
    """The runtime env this project's Ray workers need. A local Ray started under a fixed
    PYTHONHASHSEED needs none: its workers inherit the variable from the raylet, and quiet
    their own loggers where they build RLlib's parts (`quiet_ray_noise`). A runtime env
    would cost every new worker about a second (no prestarted worker can take it). Workers
    on a cluster's nodes do not inherit the driver's variables: `RAY_RUNTIME_ENV`."""
    import os

    if local and os.environ.get("PYTHONHASHSEED") is not None:
        return None
    return RAY_RUNTIME_ENV


def init_local_ray(**options: Any) -> None:
    """A local Ray for a command of this project: no dashboard unless asked, lean
    (`lean_local_ray`), and every worker with the driver's hash seed and quiet loggers
    (`worker_runtime_env`)."""
    import ray

    lean_local_ray()
    ray.init(
        address="local",
        **{"include_dashboard": False, "runtime_env": worker_runtime_env(), **options},
    )


def init_ray(
    namespace: str,
    num_cpus: int | None = None,
    dashboard: bool = False,
    metrics_port: int | None = None,
) -> str | None:
    """Join the cluster RAY_ADDRESS names, else start a local Ray with `num_cpus` CPUs (all
    when None), the dashboard if asked and its metrics served as Prometheus text on
    `metrics_port` if given; every worker as `init_local_ray` sets it up. The dashboard's
    URL, when there is one."""
    import os

    import ray

    quiet_ray_noise()
    if os.environ.get("RAY_ADDRESS"):
        if metrics_port is not None:
            print(
                "note: --metrics-port applies to a local Ray; the cluster's nodes serve "
                "their metrics on their own port (cluster/README.md, Metrics)",
                flush=True,
            )
        ctx = ray.init(namespace=namespace, runtime_env=RAY_RUNTIME_ENV)
    else:
        lean_local_ray()
        ctx = ray.init(
            address="local",
            namespace=namespace,
            num_cpus=num_cpus,
            include_dashboard=dashboard,
            runtime_env=worker_runtime_env(),
            _metrics_export_port=metrics_port,
        )
    url = getattr(ctx, "dashboard_url", None)
    return f"http://{url}" if url else None


RAY_INIT_IMPORTS = ("pydantic", "ray._common.usage.usage_lib", "ray.dashboard", "socketserver")
"""The modules `ray.init` (Ray 2.60) imports that RLlib's import also does: imported before
the two run side by side (`init_ray_importing`), since two threads importing one module
while each holds another of its cycle make one of them fail."""


def join_or_init_ray(namespace: str, num_cpus: int | None = None) -> bool:
    """The Ray this process already holds (a notebook's, a test module's), else a local one
    started here (`init_ray`); whether it started one, which its caller then shuts down."""
    import ray

    if ray.is_initialized():
        return False
    init_ray(namespace, num_cpus)
    return True


def init_ray_importing(module: str, *args: Any) -> tuple[str | None, ModuleType]:
    """`init_ray(*args)` with `module` imported meanwhile in a thread; (the dashboard's URL,
    the module). `ray.init` mostly waits on Ray's processes (the raylet registering, the
    dashboard's server): a driver's imports of RLlib and torch fit in that wait (measured on
    2 cores: the start 0.5–1.6 s shorter)."""
    import importlib
    from concurrent.futures import ThreadPoolExecutor

    for name in RAY_INIT_IMPORTS:
        importlib.import_module(name)
    with ThreadPoolExecutor(1) as aside:
        imported = aside.submit(importlib.import_module, module)
        url = init_ray(*args)
        return url, imported.result()


COLLECTOR_PAUSE_S = 30.0
"""The longest a process's start runs with the cyclic collector paused (`pause_collector`)."""

_PAUSE: dict[str, Any] = {}
"""The pause in force in this process: its timer."""


def pause_collector(limit_s: float = COLLECTOR_PAUSE_S) -> None:
    """Pause Python's cyclic garbage collector while this process starts, until
    `resume_collector` (a timer calls it after `limit_s` seconds). Importing torch, Ray and
    RLlib and building what a process runs make about a million objects that live as long as
    the process, and while they are made each full collection walks all of them so far:
    about a quarter of a command's or a Ray worker's start (results/NOTEBOOK.md, "The
    collector at a process's start"). Cycles made meanwhile wait for the resume. A collector
    paused or turned off already is left as it is."""
    import gc
    import threading

    if _PAUSE or not gc.isenabled():
        return
    gc.disable()
    timer = threading.Timer(limit_s, resume_collector)
    timer.daemon = True
    _PAUSE["timer"] = timer
    timer.start()


def resume_collector() -> None:
    """End `pause_collector`'s pause: one collection (the cycles the start left), the
    survivors frozen (they live as long as the process: later collections skip them), the
    collector on. Nothing where no pause is in force."""
    import gc

    timer = _PAUSE.pop("timer", None)
    if timer is None:
        return
    timer.cancel()
    gc.collect()
    gc.freeze()
    gc.enable()


def fixed_hash_seed(module: str, argv: list[str]) -> None:
    """Re-run this command with PYTHONHASHSEED=0 unless it is set. RLlib iterates sets of
    module ids in places (the learner's per-module work among them), and a set of strings
    iterates in an order that Python's hash seed picks per process: two runs of one config
    and seed then differ. With a fixed seed they give the same metrics on one machine."""
    import os

    if "PYTHONHASHSEED" in os.environ:
        return
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    os.execve(sys.executable, [sys.executable, "-m", module, *argv], env)


def leave(code: int | None) -> NoReturn:
    """`sys.exit(code)` at a command's end, every live object frozen first: the
    interpreter's last collection would walk the half million objects that torch, RLlib and
    Ray made, seconds at each exit of `hola_ray.run`. After a success, a Ray this process
    still holds is shut down here rather than by Ray's exit hook, which first sleeps for its
    workers' last log lines (a finished command's workers have none left; a failed one's may
    explain the failure)."""
    import gc

    gc.freeze()
    ray = sys.modules.get("ray")
    if code == 0 and ray is not None and ray.is_initialized():
        ray.shutdown()
    sys.exit(code)


def seed_torch(words) -> None:
    """This process's global torch generator from a list of integers (a SeedSequence's)."""
    import numpy as np
    import torch

    torch.manual_seed(int(np.random.SeedSequence([*words, 1]).generate_state(1)[0]))


def pin_threads(cpus) -> None:
    """torch and numba in this process on `cpus` threads (1 when RLlib says "auto").

    Ray's OMP_NUM_THREADS=1 does not reach them: a remote env runner ran torch on 2 threads
    and the simulator's parallel kernels on 2 OpenMP threads, which spin while another
    process holds the second core: beside a busy learner, or beside another evaluation
    task, sampling then ran an order of magnitude slower than on one thread. Every Ray
    worker of this project that steps the simulator or runs torch calls it with its CPU
    allotment."""
    import numba
    import torch

    threads = cpus if isinstance(cpus, int) and cpus >= 1 else 1
    torch.set_num_threads(threads)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))


def quiet_ray_noise() -> None:
    """Raise `NOISY_LOGGERS` to ERROR in this process: the driver, every worker that
    builds RLlib's parts (env runners, learners, trials), and as Ray's worker setup hook
    every worker on a cluster. Ray's C++ core still prints its own lines."""
    import logging

    for name in NOISY_LOGGERS:
        logging.getLogger(name).setLevel(logging.ERROR)
