"""A rehearsal of a lab whose gripper is a Robotiq 2F-85 on its URCap socket and whose tracker is
OptiTrack (NatNet): the rehearsal rehearses both, the gripper on the stand-in's URCap socket and the
hand as a rigid body of a stand-in Motive, through the whole cycle."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys

import pytest
from support.engine import BRIEF_PROTOCOL, protocol_toml

pytestmark = [pytest.mark.slow, pytest.mark.soak, pytest.mark.standin]  # as tests/session/test_rehearsal.py


def test_run_session_rehearse_drives_a_robotiq_gripper_that_opens_once_per_trial(tmp_path):
    """The lab file names its Robotiq's and its Motive's addresses (192.0.2.1 and .2, documentation
    addresses nothing answers at); the rehearsal points them at its stand-ins: the gripper closes on
    the object every trial (the close is a fault unless it detects it) and opens once, on the
    participant's pull; the hand is the lab's rigid body, read with the natnet client."""
    config = tmp_path / "lab.toml"
    config.write_text(f'[gripper]\nkind = "robotiq_socket"\nhost = "192.0.2.1"\nspeed = 200\n\n'
                      f'[hand_source]\nkind = "natnet"\nnatnet_server = "192.0.2.2"\n'
                      f'natnet_rigid_body = "right hand"\nunits_to_m = 1.0\n\n'
                      f"[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}")
    done = subprocess.run(
        [sys.executable, "-m", "app.cli", "run-session", "--study", str(tmp_path), "--participant",
         "R01", "--scenario", "straightforward", "--seed", "5", "--auto", "--rehearse",
         "--config", str(config), "--json", "--no-progress"],
        capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    n = 3  # BRIEF_PROTOCOL: 2 initial, 1 best
    with sqlite3.connect(tmp_path / "R01.sqlite") as db:
        outcomes = [row[0] for row in db.execute("SELECT outcome FROM trials ORDER BY trial_index")]
        released = db.execute("SELECT count(*) FROM trials WHERE release_s IS NOT NULL").fetchone()[0]
        devices = json.loads(db.execute("SELECT payload FROM events WHERE kind = 'devices_recorded'")
                             .fetchone()[0])["devices"]
    assert summary["completed"] == n and outcomes.count("completed") == n, (outcomes, done.stderr[-3000:])
    assert devices["gripper"] == "robotiq_socket" and "Robotiq 2F-85 on 127." in devices["gripper_detail"]
    assert summary["hand"].startswith("NatNet rigid body 'right hand'"), summary["hand"]
    stand_in = summary["rehearsal"]
    assert stand_in["gripper_opened"] == released == n  # once per trial, on the pull
    assert stand_in["gripper_closed"] == len(outcomes)  # each trial's prepare closed on the object
