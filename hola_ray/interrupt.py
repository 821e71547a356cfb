"""Ctrl-C that Ray cannot lose.

Python raises KeyboardInterrupt wherever the main thread is when SIGINT arrives. Inside
Ray's core worker that can be a callback that swallows it: `check_signals` turns it into
a status some waits drop, and a `cdef void` callback such as `get_py_stack` (called on
every task submission) can only print it as "ignored". The run then went on as if no
Ctrl-C came (measured: a training run interrupted right after a generation finished the
next one and exited 0). `install` keeps the request: the handler records it before it
raises, and `check`, called by the long loops (every Oracle iteration, every Grapher
batch, every generation), raises KeyboardInterrupt again until the run has stopped.
"""

from __future__ import annotations

import signal
import threading

_requested = threading.Event()


def _handler(signum, frame) -> None:  # noqa: ARG001
    _requested.set()
    raise KeyboardInterrupt


def install() -> None:
    """Take over SIGINT in the main thread (after `ray.init`, which may set its own)."""
    _requested.clear()
    signal.signal(signal.SIGINT, _handler)


def requested() -> bool:
    return _requested.is_set()


def check() -> None:
    """Raise KeyboardInterrupt if Ctrl-C came, even if the first one was swallowed."""
    if _requested.is_set():
        raise KeyboardInterrupt
