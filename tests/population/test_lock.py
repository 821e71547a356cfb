"""The run-directory lock: a second run is refused before it writes anything, a killed
run's lock is taken over with a message, and `python -m hola_ray.run` says so."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hola_ray.population.lock import RunDirLocked, RunLock

ROOT = Path(__file__).resolve().parents[2]


def test_a_held_run_directory_is_refused_naming_its_holder(tmp_path):
    with RunLock(tmp_path / "run") as first:
        assert first.held
        with pytest.raises(RunDirLocked, match=rf"in use by another run \(pid {os.getpid()} on "):
            RunLock(tmp_path / "run").acquire()
    # released: the next run takes it without a word
    again = RunLock(tmp_path / "run")
    assert again.acquire() is None
    again.release()


def test_the_lock_of_a_killed_run_is_taken_over_with_a_message(tmp_path):
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from hola_ray.population.lock import RunLock; "
            "RunLock(sys.argv[1]).acquire(); print('held', flush=True); time.sleep(60)",
            str(tmp_path / "run"),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "held"
    with pytest.raises(RunDirLocked, match=f"pid {holder.pid}"):
        RunLock(tmp_path / "run").acquire()
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    lock = RunLock(tmp_path / "run")
    note = lock.acquire()
    assert note and f"pid {holder.pid}" in note and "no longer runs" in note
    assert json.loads((tmp_path / "run" / ".lock").read_text())["pid"] == os.getpid()
    lock.release()


def test_a_second_run_on_a_used_folder_is_refused_before_ray_starts(tmp_path):
    out = tmp_path / "run"
    smoke = ROOT / "configs" / "smoke.yaml"
    with RunLock(out):
        cmd = [sys.executable, "-m", "hola_ray.run", "--config", str(smoke), "--out", str(out)]
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert f"error: {out} is in use by another run (pid {os.getpid()}" in done.stderr
    assert sorted(p.name for p in out.iterdir()) == [".lock"]  # nothing written
    assert "Ray dashboard" not in done.stdout and "training run" not in done.stdout
