"""``DeferredSignals`` (``manager.bus.signals``): what the recorder holds SIGINT and SIGTERM with while it hands a
batch over. Each case runs in a process of its own, whose handlers it may change and which a signal may end."""
from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")

HELD = """
import os, signal
from zencosim.manager.bus.signals import DeferredSignals
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_DFL)
deferred = DeferredSignals()
with deferred.held():
    os.kill(os.getpid(), signal.SIGINT)
    os.kill(os.getpid(), signal.SIGTERM)
    print("inside", flush=True)
print("after", flush=True)
"""


def test_every_signal_held_through_a_block_acts_as_before_once_the_block_ends():
    """An ignored SIGINT and a SIGTERM with its default action, both arriving inside the block: the block runs to
    its end, then SIGINT is ignored and SIGTERM ends the process — the second signal is not lost behind the first."""
    result = subprocess.run([sys.executable, "-c", HELD], capture_output=True, text=True, timeout=120)
    assert (result.stdout, result.returncode) == ("inside\n", -signal.SIGTERM), result.stderr


RESTORED = """
import signal
from zencosim.manager.bus.signals import DeferredSignals
def mine(*_): pass
signal.signal(signal.SIGTERM, mine)
deferred = DeferredSignals()
assert signal.getsignal(signal.SIGTERM) is not mine
deferred.restore()
print(signal.getsignal(signal.SIGTERM) is mine, signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


def test_restore_puts_back_the_handlers_that_were_there():
    result = subprocess.run([sys.executable, "-c", RESTORED], capture_output=True, text=True, timeout=120)
    assert result.stdout == "True True\n", result.stderr
