"""The Robotiq 2F-85 on its URCap socket (robot_io.grippers.robotiq) against the stand-in's socket over
real TCP (one loopback address per test): activation, the close on the object and the open, what is sent, and
each fault — a URCap that stops answering, a fault code, the object lost, nothing listening."""

from __future__ import annotations

import pytest
from support.robotiq import await_fault, connected_gripper, robotiq_config, robotiq_state
from support.ur import standin
from support.waiting import wait_for

from app.cli import main
from app.session.rehearsal import free_loopback_host
from robot_io.config import ControllerConfig
from robot_io.errors import GripperFault
from robot_io.grippers.robotiq import Obj, RobotiqSocketGripper, probe
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import RigSpec
from robot_io.standins.urcap import DEFAULT_OBJECT_POSITION

# the stand-in in real time, as the other stand-in tests: `make soak` repeats them
pytestmark = [pytest.mark.soak, pytest.mark.standin]


def activations(ur) -> int:
    return ur.control("events")["events"].count("robotiq: activated")


def test_the_gripper_is_activated_on_connect_only_if_it_is_not():
    with standin() as ur:
        assert probe(ur.host, robotiq_config(ur.host)).sta == 0  # a gripper just powered on
        with connected_gripper(ur) as gripper:
            assert gripper.status.sta == 3 and robotiq_state(ur)["sta"] == 3
        with connected_gripper(ur) as again:
            assert again.status.sta == 3
        assert activations(ur) == 1  # the second connection found it activated: no reset, no cycle


def test_close_detects_the_object_and_open_releases_it():
    with standin() as ur, connected_gripper(ur) as gripper:
        assert not gripper.holding and gripper.detected is None
        gripper.close()
        assert gripper.holding and gripper.detected
        assert gripper.status.obj is Obj.CONTACT_CLOSING and gripper.status.pos == DEFAULT_OBJECT_POSITION
        assert robotiq_state(ur)["obj"] == 2
        gripper.open()
        assert not gripper.holding  # as commanded, at once: the control loop does not wait
        state = wait_for(lambda: (s := robotiq_state(ur))["obj"] == 3 and s["position"] == 0 and s,
                         "the stand-in's fingers open at 0", seen=lambda: robotiq_state(ur))
        assert state["pre"] == 0
        wait_for(lambda: gripper.status.pos == 0, "the gripper's worker to see the open end",
                 seen=lambda: gripper.status)
        assert gripper.detected is False
        gripper.check()  # no fault


def test_position_speed_and_force_are_sent_as_configured():
    settings = {"speed": 100, "force": 30, "open_position": 10, "closed_position": 230}
    with standin() as ur, connected_gripper(ur, **settings) as gripper:
        gripper.close()
        state = robotiq_state(ur)
        assert (state["pre"], state["spe"], state["force"], state["gto"]) == (230, 100, 30, 1)
        events = ur.control("events")["events"]
        assert "robotiq: closing to 230 (speed 100, force 30)" in events
        gripper.open()
        wait_for(lambda: robotiq_state(ur)["position"] == 10 and robotiq_state(ur)["obj"] == 3,
                 "the fingers at the open position 10", seen=lambda: robotiq_state(ur))
        assert robotiq_state(ur)["pre"] == 10


def test_nothing_to_close_on_is_a_fault_naming_the_object_until_it_is_loaded():
    with standin() as ur, connected_gripper(ur) as gripper:
        ur.control("configure_robotiq", object_position=None)
        with pytest.raises(GripperFault, match=r"without detecting an object.*opened again"):
            gripper.close()
        assert not gripper.holding and gripper.detected is False
        assert robotiq_state(ur)["position"] == 0  # opened again, to be loaded
        ur.control("configure_robotiq", object_position=DEFAULT_OBJECT_POSITION)  # the next trial's
        gripper.close()
        assert gripper.holding and gripper.detected


def test_a_urcap_that_stops_answering_mid_hold_is_a_clear_fault():
    with standin() as ur, connected_gripper(ur, reply_timeout_s=0.5) as gripper:
        gripper.close()
        ur.control("configure_robotiq", answering=False)
        fault = await_fault(gripper, ur, "the silent URCap's fault")
        assert f"Robotiq URCap on {ur.host}:63352 did not answer" in str(fault)
        assert "reply_timeout_s = 0.5 s" in str(fault)
        assert not gripper.holding
        with pytest.raises(GripperFault, match="did not answer"):  # and the next trial's close
            gripper.close()


def test_recover_connects_the_gripper_again_once_the_urcap_answers():
    """The rig's recovery (the dashboard's Recover arm, which a gripper fault now requires before the
    next Start) is refused while the URCap is still silent, and connects the gripper again once it
    answers: the next close holds the object."""
    with standin() as ur:
        devices = RigDevices(RigSpec(config=ControllerConfig(gripper=robotiq_config(
            ur.host, reply_timeout_s=0.5)), scenario=Scenario.STRAIGHTFORWARD))
        try:
            devices.gripper.close()
            ur.control("configure_robotiq", answering=False)
            fault = await_fault(devices.gripper, ur, "the silent URCap's fault")
            with pytest.raises(GripperFault, match=r"URCap on .* did not answer"):
                devices.recover(inspected=True)  # still silent: refused, saying why
            ur.control("configure_robotiq", answering=True)
            assert devices.recover(inspected=True) == f"gripper connected again after: {fault}"
            devices.gripper.check()  # no fault
            devices.gripper.close()
            assert devices.gripper.holding and devices.gripper.detected
        finally:
            devices.close()


def test_a_fault_code_is_reported_while_holding_and_when_connecting():
    with standin() as ur:
        with connected_gripper(ur) as gripper:
            gripper.close()
            ur.control("configure_robotiq", fault=8)
            fault = await_fault(gripper, ur, "the fault code's fault")
            assert "reports fault code 8 (GET FLT) while holding" in str(fault)
        with pytest.raises(GripperFault, match=r"reports fault code 8 .*teach pendant"):
            RobotiqSocketGripper(ur.host, robotiq_config(ur.host))


def test_the_object_lost_while_holding_is_a_fault_the_next_close_clears():
    with standin() as ur, connected_gripper(ur) as gripper:
        gripper.close()
        ur.control("configure_robotiq", object_position=None)  # it slips out
        fault = await_fault(gripper, ur, "the lost object's fault")
        assert "the object was lost while holding (OBJ went from 2 to" in str(fault)
        gripper.open()  # it still opens: a lost object leaves the gripper sound
        wait_for(lambda: robotiq_state(ur)["position"] == 0, "the fingers open at 0",
                 seen=lambda: robotiq_state(ur))
        ur.control("configure_robotiq", object_position=DEFAULT_OBJECT_POSITION)  # loaded again
        gripper.close()
        assert gripper.holding
        gripper.check()


def test_no_urcap_answering_is_a_clear_fault():
    host = free_loopback_host()  # nothing listens there
    with pytest.raises(GripperFault, match=f"no Robotiq URCap answering on {host}:63352"):
        RobotiqSocketGripper(host, robotiq_config(host))


def test_check_devices_reports_activation_and_position_and_moves_nothing(tmp_path, capsys):
    with standin() as ur:
        lab = tmp_path / "lab.toml"
        lab.write_text(f'[gripper]\nkind = "robotiq_socket"\nhost = "{ur.host}"\n')
        assert main(["check-devices", "--ur-host", ur.host, "--config", str(lab)]) == 0
        before = capsys.readouterr().out
        with connected_gripper(ur) as gripper:
            gripper.close()
        assert main(["check-devices", "--ur-host", ur.host, "--config", str(lab)]) == 0
        after = capsys.readouterr().out
        ur.control("configure_robotiq", fault=8)
        assert main(["check-devices", "--ur-host", ur.host, "--config", str(lab)]) == 1
        faulted = capsys.readouterr().out
    assert (f"gripper: Robotiq URCap on {ur.host}:63352, NOT activated (STA 0), position 0/255"
            in before) and "it activates when the rig opens it" in before
    assert f"activated, position {DEFAULT_OBJECT_POSITION}/255, OBJ 2" in after and "(not moved)" in after
    assert "gripper: NOT OK — Robotiq URCap" in faulted and "fault code 8" in faulted
