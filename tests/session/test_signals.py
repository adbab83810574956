"""serve's wait for Ctrl-C (app.session.signals): a signal the kernel hands to another thread of the
process still ends the wait. An ``Event.wait()`` in the main thread slept on (serve never closed
after a SIGINT that came just after a SIGCONT, one run in three of tests/protocol/test_two_writers.py)."""

from __future__ import annotations

import subprocess
import sys

from support.waiting import CEILING_S

#: A process that waits for the quit signal while another thread sends SIGTERM to itself (only
#: that thread gets it: pthread_kill), then says it closed. The thread first gives the main thread
#: time to fall asleep in the wait (the case that hung; a signal that comes sooner is the easy one,
#: so a slow machine makes this test weaker, never flaky).
WAITER = """
import signal, threading, time
from app.session.signals import QuitSignal
def send():
    time.sleep(0.3)
    signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
with QuitSignal() as quit_signal:
    threading.Thread(target=send, daemon=True).start()
    quit_signal.wait()
print("closed")
"""


def test_a_quit_signal_that_lands_on_another_thread_ends_the_wait():
    done = subprocess.run([sys.executable, "-c", WAITER], capture_output=True, text=True,
                          timeout=CEILING_S)  # a ceiling for the hang this test is about
    assert (done.returncode, done.stdout.strip()) == (0, "closed"), done.stderr


def test_a_quit_signal_before_the_wait_is_not_lost():
    waiter = WAITER.replace("threading.Thread(target=send, daemon=True).start()",
                            "signal.raise_signal(signal.SIGINT)")
    done = subprocess.run([sys.executable, "-c", waiter], capture_output=True, text=True,
                          timeout=CEILING_S)
    assert (done.returncode, done.stdout.strip()) == (0, "closed"), done.stderr
