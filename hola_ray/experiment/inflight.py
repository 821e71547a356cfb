"""The trials of one `Runner.train` in the air: started `width` at a time, each in a placement
group of its own, landed as they end, and resubmitted when their node was lost."""

from __future__ import annotations

import time
from typing import Any

from hola_ray.experiment.tasks import trial_state

# ---- a trial lost with its node ----------------------------------------------------------
LOST_WITH_A_NODE = (
    "NodeDiedError",
    "WorkerCrashedError",
    "ActorDiedError",
    "ActorUnavailableError",
    "OwnerDiedError",
    "ObjectLostError",
    "LocalRayletDiedError",
)
"""Ray's errors for a task or actor that died with its process or node, not of its own
fault (a trial's own exception arrives as a RayTaskError of that exception)"""


def node_lost(err: BaseException) -> bool:
    """Whether a trial's failure is its node's (or a process's it needs): the error, or
    what a RayTaskError carries, is one of `LOST_WITH_A_NODE`."""
    import ray.exceptions as rx

    kinds = tuple(getattr(rx, n) for n in LOST_WITH_A_NODE if hasattr(rx, n))
    seen: BaseException | None = err
    for _ in range(8):  # a chain of tasks' errors, never a cycle
        if seen is None:
            return False
        if isinstance(seen, kinds):
            return True
        seen = getattr(seen, "cause", None) or seen.__cause__
    return False


class InFlight:
    """The trials of one `Runner.train` in the air: which are waiting, placing and
    running, which failed, and how often each was lost with its node. `runner` is the
    `Runner` (not imported here: it imports this module)."""

    def __init__(self, runner: Any, remote: Any, states: dict, todo: list[str]) -> None:
        import ray

        self.runner, self.remote, self.states = runner, remote, states
        self.token, self.here = runner.token(), ray.get_runtime_context().get_node_id()
        self.running: dict[Any, str] = {}
        self.groups: dict[str, Any] = {}
        self.placing: dict[str, Any] = {}  # trial → its group's ready(), until it is placed
        self.started: dict[str, float] = {}
        self.failed: dict[str, str] = {}
        self.lost: dict[str, int] = dict.fromkeys(todo, 0)
        self.waiting = list(todo)

    def fly(self, width: int) -> None:
        """Until every trial finished or failed: `width` at a time, a progress line when
        it changed (and at least once a minute)."""
        import ray

        r = self.runner
        last_view, last_line = 0.0, ""
        while self.waiting or self.running:
            while self.waiting and len(self.running) < width:
                self.submit(self.waiting.pop(0))
            ready, _ = ray.wait(list(self.running), num_returns=1, timeout=r.poll_s)
            for ref in ready:
                self.land(ref)
            for t, ref in list(self.placing.items()):
                if ray.wait([ref], timeout=0)[0]:
                    del self.placing[t]
            line = r.view(self.running.values(), self.waiting, self.failed, self.placing)
            if line != last_line or time.monotonic() - last_view >= 60.0:
                r.say(f"[{time.strftime('%H:%M:%S')}] {line}")
                last_view, last_line = time.monotonic(), line

    def submit(self, t: str) -> None:
        """Start trial `t` in a placement group of its own."""
        from hola_ray.experiment.mirror import pack

        r = self.runner
        self.groups[t], options = r.place(t)
        self.placing[t] = self.groups[t].ready()
        # a partial trial starts from the driver's copy wherever it lands
        partial = self.states[t][0] == "partial"
        ref = self.remote.options(**options).remote(
            r.configs[t],
            str(r.trial_dir(t).resolve()),
            self.token,
            self.here,
            pack(r.trial_dir(t)) if partial else None,
            r.mirror_of(t),
            r.donors(t),
        )
        self.running[ref] = t
        self.started[t] = time.monotonic()

    def land(self, ref: Any) -> None:
        """A trial that ended: done, resubmitted when its node was lost (up to
        `Runner.max_lost` times), or failed."""
        import ray

        r, t = self.runner, self.running.pop(ref)
        try:
            how = ray.get(ref)
            r.say(f"{t}: done in {(time.monotonic() - self.started[t]) / 60:.1f} min ({how})")
        except Exception as err:  # noqa: BLE001 - one failed trial must not stop the rest
            if node_lost(err) and self.lost[t] < r.max_lost:
                self.lost[t] += 1
                self.states[t] = trial_state(r.trial_dir(t), r.configs[t].generations)
                last = self.states[t][1]
                r.say(
                    f"{t}: lost with its node ({type(err).__name__}); resubmitted "
                    + (f"after generation {last}" if last is not None else "afresh")
                    + f" ({self.lost[t]} of {r.max_lost})"
                )
                self.waiting.insert(0, t)
            else:
                why = str(err).strip().splitlines()[-1][:300]
                self.failed[t] = f"{type(err).__name__}: {why}"
                r.say(f"{t}: FAILED: {self.failed[t]}")
        ray.util.remove_placement_group(self.groups.pop(t))
        self.placing.pop(t, None)

    def release(self) -> None:
        """Remove the placement groups still held (the run stopped or failed)."""
        import ray

        for group in self.groups.values():
            ray.util.remove_placement_group(group)
