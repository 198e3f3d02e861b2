"""Ctrl-C and SIGTERM as a stop request (framework/runtime/stop_signals.py, docs/reliability.md)."""

import os
import signal

import pytest

from handflow.framework.runtime.stop_signals import StopSignals


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_inside_the_block_asks_to_stop_and_raises_nothing(sig):
    before = signal.getsignal(sig)
    with StopSignals() as stop:
        assert not stop.is_set()
        os.kill(os.getpid(), sig)
        assert stop.wait(10), "the signal did not reach the handler"
    assert signal.getsignal(sig) is before  # the previous handler is back


def test_after_the_block_ctrl_c_raises_again():
    with StopSignals():
        pass
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):  # the handler runs at the next bytecode boundary
            pass
