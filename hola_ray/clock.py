"""Where a run's time goes: seconds per phase, one account per metrics row.

A row's account spans the wall time from the end of the previous row's account (or from
the start of the command, for the first row a process writes) to the start of the row's
own commit. So the rows of one process add up to its wall time but for the last commit, a
row's start-up phases (Ray, actors, building the Oracle) land in the first row a process
writes (generation 0, or the first generation after a resume), and the previous row's
commit (its files) lands in the next row as `commit`: a row cannot time its own writing.
What no phase covers is `other`.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

PHASES = (
    ("process", "the command's start: imports and Ray (first row of a process)"),
    ("actors", "the coordinator and evaluation actors' start, as the driver waits for them"),
    (
        "population",
        "generation 0 loaded (a shipped population, another run's), and the validation teammates",
    ),
    ("pretrain", "generation 0 trained here (MEP pre-training, FCP's self-play agents)"),
    ("oracle_build", "the Oracle built: RLlib's algorithm, its env runners and learner"),
    ("seat", "partners and φ pushed into the Oracle, its generators reseeded"),
    ("oracle_sample", "the Oracle sampling that the update did not hide"),
    ("oracle_update", "the Oracle's learner update (GAE, minibatches, gradient steps)"),
    ("export", "the learner's weights read back and exported"),
    ("grapher", "the hyperedges weighed (the learner's, or G_0's at generation 0)"),
    ("coordinator", "η, φ and the decision"),
    ("monitors", "the previous row's monitors (validation, judges) waited for and written"),
    ("commit", "the previous row's files: generation folder, best.pt, learner.pt"),
    ("other", "what no phase covers"),
)
"""(phase, what it times), in the order a run meets them; a row's `time_<phase>_s`."""

NAMES = tuple(name for name, _ in PHASES)


def column(phase: str) -> str:
    """The metrics column of a phase: `time_<phase>_s`."""
    return f"time_{phase}_s"


class PhaseClock:
    """Accumulates seconds per phase since `since` (a `time.perf_counter()` reading)."""

    def __init__(self, since: float | None = None) -> None:
        self.since = time.perf_counter() if since is None else since
        self.seconds: dict[str, float] = {}

    @contextmanager
    def phase(self, name: str) -> Iterator[None]:
        """Time the block as `name` (added to what the phase already holds)."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - start)

    def add(self, name: str, seconds: float) -> None:
        if name not in NAMES or name == "other":
            raise ValueError(f"no phase {name!r}; phases: {NAMES[:-1]}")
        self.seconds[name] = self.seconds.get(name, 0.0) + max(float(seconds), 0.0)

    def close(self) -> dict[str, float]:
        """The account so far as metrics (`wall_s` and every phase's column, `other` the
        rest), and a new account from now on."""
        now = time.perf_counter()
        wall = now - self.since
        row = {"wall_s": round(wall, 2)}
        for name in NAMES[:-1]:
            if name in self.seconds:
                row[column(name)] = round(self.seconds[name], 3)
        row[column("other")] = round(max(wall - sum(self.seconds.values()), 0.0), 3)
        self.since, self.seconds = now, {}
        return row


def process_start() -> float:
    """When this process started, on `time.perf_counter()`'s clock (a command's first
    row counts its imports and Ray's start from here): read from /proc on Linux (the
    start of the process, before a re-exec under the fixed hash seed too); elsewhere now."""
    import os

    try:
        with open(f"/proc/{os.getpid()}/stat") as stat:
            ticks = int(stat.read().rsplit(")", 1)[1].split()[19])
        age = time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        age = 0.0
    return time.perf_counter() - max(age, 0.0)
