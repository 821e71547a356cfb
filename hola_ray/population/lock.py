"""An exclusive lock on a run directory for a run's whole life.

`RunLock(run_dir).acquire()` takes `RUN_DIR/.lock` with `flock`: a second run on the same
directory is refused before it writes anything, naming the run that holds it. The kernel
releases a flock when its process ends, however it ends (SIGKILL included), so a killed
driver never leaves the directory locked; the file still names that holder, and the next
run says that it takes the lock over. flock is per machine: on a cluster, trials of one
experiment run in their own directories, and two drivers on different nodes sharing a
network file system are not guarded against each other (NFS may not honour flock).
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import time
from pathlib import Path
from typing import Any

LOCK_NAME = ".lock"


class RunDirLocked(RuntimeError):
    """Another live run holds the run directory."""


def _describe(holder: dict[str, Any]) -> str:
    since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(holder.get("since", 0)))
    return f"pid {holder.get('pid')} on {holder.get('host')}, since {since}"


class RunLock:
    """The lock of one run directory; a context manager, or `acquire` / `release`."""

    def __init__(self, run_dir: str | Path):
        self.root = Path(run_dir)
        self.path = self.root / LOCK_NAME
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> str | None:
        """Take the lock; returns a line to show when it took over a dead run's lock.
        Raises `RunDirLocked` when a live run holds it."""
        if self._fd is not None:
            return None
        self.root.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read(fd)
            os.close(fd)
            who = _describe(holder) if holder else "another process"
            raise RunDirLocked(
                f"{self.root} is in use by another run ({who}); wait for it to end or give "
                "another --out"
            ) from None
        previous = _read(fd)
        os.ftruncate(fd, 0)
        mine = {"pid": os.getpid(), "host": socket.gethostname(), "since": time.time()}
        os.pwrite(fd, json.dumps(mine).encode(), 0)
        self._fd = fd
        if previous:
            return (
                f"taking over the lock of {self.root} from {_describe(previous)}: it no longer runs"
            )
        return None

    def release(self) -> None:
        """Free the lock (and say nobody holds it)."""
        if self._fd is None:
            return
        os.ftruncate(self._fd, 0)
        fcntl.flock(self._fd, fcntl.LOCK_UN)
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> RunLock:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _read(fd: int) -> dict[str, Any]:
    data = os.pread(fd, 4096, 0)
    try:
        return json.loads(data) if data else {}
    except ValueError:
        return {}
