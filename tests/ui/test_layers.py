"""app/ui renders and forwards only: no module of it constructs a device or touches the store."""

from __future__ import annotations

from pathlib import Path

from support.imports import statements

import app.ui

#: What a screen may not import: devices, the rig, the store and its database, the engine.
FORBIDDEN = ("robot_io.arms.mock_arm", "robot_io.arms.ur_arm", "robot_io.rig", "robot_io.devices",
             "robot_io.grippers.gripper", "robot_io.hands.lsl_hand", "robot_io.hands.udp_hand",
             "robot_io.control.trial", "robot_io.control.loop", "robot_io.control.cycle",
             "robot_io.standins.hand_publisher", "robot_io.standins.ur",
             "session_store.store", "session_store.export", "sqlite3", "sqlite_utils",
             "app.protocol.engine", "app.session.rehearsal")
FORBIDDEN_NAMES = {"SimulatedHand", "MockArm", "URArm", "ParticipantStore", "SessionEngine",
                   "RigClient", "Rehearsal"}


def test_no_ui_module_imports_a_device_the_rig_or_the_store():
    files = sorted(Path(app.ui.__file__).parent.glob("*.py"))
    assert len(files) >= 6
    offending = [(path.name, module, name) for path in files
                 for module, name, _, _ in statements(path)
                 if module.startswith(FORBIDDEN) or name in FORBIDDEN_NAMES]
    assert offending == []
