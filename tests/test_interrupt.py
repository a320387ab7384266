"""SIGINT deferred to the master's next check between steps."""

from __future__ import annotations

import os
import signal

import pytest

from dronefly.interrupt import deferred_sigint


def test_sigint_sets_a_flag_instead_of_raising():
    with deferred_sigint() as stop:
        assert not stop.requested
        os.kill(os.getpid(), signal.SIGINT)
        signal.getsignal(signal.SIGINT)  # bytecodes run: the handler has been called
        assert stop.requested
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_third_sigint_raises():
    with pytest.raises(KeyboardInterrupt):
        with deferred_sigint():
            for _ in range(3):
                os.kill(os.getpid(), signal.SIGINT)
                signal.getsignal(signal.SIGINT)
