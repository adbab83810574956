"""The store defines the study's vocabulary and knows nothing of the application (the protocol, the
simulator, the learner)."""

from __future__ import annotations

import subprocess
import sys


def test_session_store_imports_no_simulator_protocol_or_learner():
    loaded = subprocess.run(
        [sys.executable, "-c", "import sys, session_store.store, session_store.export, "
         "session_store.integrity, session_store.catalog, session_store.lock; "
         "print(' '.join(sorted(m for m in sys.modules if m.startswith(('app', 'robot_io')))))"],
        capture_output=True, text=True, check=True).stdout.split()
    assert set(loaded) == {"robot_io", "robot_io.errors", "robot_io.control",
                           "robot_io.control.recorder", "robot_io.theta"}
