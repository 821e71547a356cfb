"""Progress without a terminal is plain lines, never carriage returns."""

from __future__ import annotations

from hola_ray.progress import PlainProgress, progress


def test_without_a_terminal_progress_is_plain_lines(capsys, monkeypatch):
    monkeypatch.setattr(PlainProgress, "interval_s", 0.0)
    with progress(1000, "gen 3 oracle", "step") as bar:  # stderr is captured: no terminal
        assert isinstance(bar, PlainProgress)
        for _ in range(4):
            bar.update(250)
            bar.set_postfix(ret="1.5", sps="900")
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 5  # one per update (interval 0) and one at the end
    assert lines[-1].startswith("gen 3 oracle: 1,000 / 1,000 step (100%)")
    assert lines[-1].endswith("; ret 1.5, sps 900")


def test_a_disabled_progress_says_nothing(capsys):
    with progress(10, "quiet", "ep", enabled=False) as bar:
        bar.update(10)
    assert capsys.readouterr().err == ""


def test_a_command_reruns_itself_under_the_fixed_hash_seed(tmp_path):
    """Without PYTHONHASHSEED the command re-runs as `python -m <module>` with it set to 0,
    so two runs hash strings alike; `hola_ray.run` and `hola_ray.experiment` do it before
    their heavy imports."""
    import os
    import subprocess
    import sys

    (tmp_path / "probe.py").write_text(
        "import os, sys\nprint(os.environ['PYTHONHASHSEED'], hash('hola'), sys.argv[1:])\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONHASHSEED"}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    code = (
        "import sys; from hola_ray.process import fixed_hash_seed; "
        "fixed_hash_seed('probe', sys.argv[1:])"
    )

    def said() -> str:
        cmd = [sys.executable, "-c", code, "--x", "1"]
        return subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout

    first = said()
    assert first.startswith("0 ") and first.strip().endswith("['--x', '1']")
    assert said() == first
    # the commands' modules import no torch, Ray or RLlib before they re-run themselves
    for modules in ("hola_ray.commands.run", "hola_ray.experiment, hola_ray.experiment.command"):
        probe = f"import sys, {modules}; print(sorted({{'torch', 'ray'}} & set(sys.modules)))"
        cmd = [sys.executable, "-c", probe]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True)
        assert out.stdout.strip() == "[]", (modules, out.stderr[-2000:])
    # and the experiment's names still load, each from its module
    import hola_ray.experiment as experiment

    assert experiment.Runner.__module__ == "hola_ray.experiment.runner"
    assert all(getattr(experiment, name) is not None for name in experiment.__all__)


def test_a_command_leaves_with_its_code_and_every_object_frozen():
    """`leave(code)` exits with the command's code, the live objects moved out of the
    collector's reach (the interpreter's last collection then skips them)."""
    import gc

    import pytest

    from hola_ray.process import leave

    made = [[] for _ in range(5000)]  # live, and not frozen yet (the collection froze its own)
    before = gc.get_freeze_count()
    try:
        with pytest.raises(SystemExit) as exit_:
            leave(3)
        assert exit_.value.code == 3
        assert gc.get_freeze_count() >= before + len(made)
    finally:
        gc.unfreeze()


_PAUSED_START = """
import gc, time, weakref
from hola_ray import process

class Node:
    pass

process.pause_collector(limit_s=float(__import__("sys").argv[1]))
assert not gc.isenabled()
process.pause_collector()  # paused already: one pause, one timer
cycle = Node()
cycle.self = cycle
made = weakref.ref(cycle)
del cycle
time.sleep(0.3)
if __import__("sys").argv[1] == "999":
    assert not gc.isenabled() and made() is not None  # paused: the cycle waits
    process.resume_collector()
else:
    time.sleep(0.7)
assert gc.isenabled() and gc.get_freeze_count() > 0, (gc.isenabled(), gc.get_freeze_count())
assert made() is None  # the resume's collection took the cycle made while paused
gc.disable()  # turned off by someone else: a pause leaves it off, and no resume turns it on
process.pause_collector()
process.resume_collector()
assert not gc.isenabled()
print("ok")
"""


def test_a_paused_collector_resumes_collected_and_frozen_by_its_timer_or_a_call():
    """`pause_collector` (a command's or a local Ray worker's start): the collector off until
    its timer or `resume_collector`, which collects the cycles made meanwhile, freezes the
    survivors and turns it on. In a process of its own: the suite's keeps its collector."""
    import subprocess
    import sys

    for limit_s in ("0.2", "999"):  # the timer ends the pause; a call ends it first
        done = subprocess.run(
            [sys.executable, "-c", _PAUSED_START, limit_s], capture_output=True, text=True
        )
        assert done.stdout.strip() == "ok", (limit_s, done.stderr[-2000:])


def test_a_finished_command_shuts_its_ray_down_before_ray_s_exit_hook(monkeypatch):
    """After a success `leave` shuts Ray down itself (Ray's exit hook would sleep 0.5 s
    first); after a failure it leaves Ray's hook to do it, with the workers' last lines."""
    import gc
    import sys
    from types import SimpleNamespace

    import pytest

    from hola_ray.process import leave

    calls: list[str] = []
    ray = SimpleNamespace(is_initialized=lambda: True, shutdown=lambda: calls.append("shut"))
    monkeypatch.setitem(sys.modules, "ray", ray)
    try:
        for code, shut in ((1, []), (0, ["shut"])):
            with pytest.raises(SystemExit):
                leave(code)
            assert calls == shut
    finally:
        gc.unfreeze()


def test_the_cluster_workers_setup_hook_names_a_function_that_exists():
    """Workers on a cluster's nodes (and a local Ray started without a fixed hash seed) run
    `RAY_RUNTIME_ENV`'s setup hook first: a name that does not import makes every worker
    fail at its start, and Ray starts them again and again (a benchmark hung so, 584 worker
    logs in 9 minutes, when the hook still named its old module)."""
    import importlib

    from hola_ray.process import RAY_RUNTIME_ENV, worker_runtime_env

    module, _, name = RAY_RUNTIME_ENV["worker_process_setup_hook"].rpartition(".")
    hook = getattr(importlib.import_module(module), name)
    assert callable(hook)
    hook()  # runs in a plain process too
    assert worker_runtime_env(local=False) == RAY_RUNTIME_ENV
