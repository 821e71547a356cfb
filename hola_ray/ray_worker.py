"""The Python worker of a local Ray this project starts (`hola_ray.third_party.LEAN_LOCAL_RAY`
names this file as Ray's `worker_path`): Ray's own `default_worker.py`, run as Ray runs it,
with the cyclic collector paused while the worker starts (`hola_ray.process.pause_collector`:
the worker imports Ray, then whatever its actor or task needs, torch and RLlib among them).

Run as a script, this file's folder would head `sys.path` and its neighbours (`config`,
`env`, `process`, …) would shadow any top-level module of those names: the folder Ray's
own script would have there takes its place before anything else is imported."""

import os
import sys
from importlib.util import find_spec


def default_worker() -> str:
    """The path of Ray's own worker script, found without importing Ray."""
    (ray_dir,) = find_spec("ray").submodule_search_locations
    return os.path.join(ray_dir, "_private", "workers", "default_worker.py")


if __name__ == "__main__":
    path = default_worker()
    sys.path[0] = os.path.dirname(path)
    from hola_ray.process import pause_collector

    pause_collector()
    import runpy

    sys.argv[0] = path
    runpy.run_path(path, run_name="__main__")
