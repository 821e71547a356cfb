"""A Ctrl-C swallowed where it landed (as Ray's callbacks can) still stops the run."""

from __future__ import annotations

import os
import signal

import pytest

from hola_ray import interrupt


def test_a_swallowed_ctrl_c_is_raised_again_at_the_next_check():
    before = signal.getsignal(signal.SIGINT)
    try:
        interrupt.install()
        interrupt.check()  # nothing asked yet
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs between bytecodes
                pass
        except KeyboardInterrupt:
            pass  # what a callback inside Ray does with it
        assert interrupt.requested()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()  # until the run stops, every check raises
        interrupt.install()  # a new run starts clean
        interrupt.check()
    finally:
        signal.signal(signal.SIGINT, before)
