"""The tool-output gripper's link after an RTDE drop (issue 38, item 2): it goes through the UR's
RTDE server, so what drops the arm's link drops it too. Before, the arm's recovery reconnected the
arm only; the next trial held the object out and its release failed ("write: Broken pipe"), ending
the rig process. Now the recovery connects the gripper again, and a switch on a dead link is a
gripper fault (the trial ends, the arm stops), never an error that ends the rig.

Real ur_rtde clients (``RTDEIOInterface`` among them) against the stand-in controller.
"""

from __future__ import annotations

import pytest
from support.priority import realtime_threads
from support.ur import standin
from support.waiting import wait_for

from robot_io.arms.arm import ArmState
from robot_io.config import ControllerConfig
from robot_io.errors import ArmFault
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import RigSpec

pytestmark = [pytest.mark.slow, pytest.mark.standin]

TOOL_OUTPUT = 0


def rig_config(host: str) -> ControllerConfig:
    return ControllerConfig.model_validate({"arm": {"kind": "ur"}, "ur": {"host": host},
                                            "gripper": {"kind": "tool_output",
                                                        "tool_output": TOOL_OUTPUT,
                                                        "open_level": False}})


def test_the_arms_recovery_after_an_rtde_drop_connects_the_gripper_again():
    with standin() as ur, realtime_threads():
        devices = RigDevices(RigSpec(config=rig_config(ur.host), scenario=Scenario.PERTURBED))
        try:
            def output() -> bool:
                return bool(ur.control("state")["tool_outputs"] >> TOOL_OUTPUT & 1)

            devices.gripper.close()  # closed: the output high (open_level False)
            wait_for(output, "the stand-in's tool output high after close", seen=output)
            assert ur.control("drop_sockets")["ok"]
            with pytest.raises(ArmFault):  # the arm finds its link gone, as a trial's loop would
                wait_for(lambda: devices.connected.move_to(devices.config.scene.point("robot_start")),
                         "the arm to notice the dropped link")
            assert devices.connected.state is ArmState.FAULT
            said = devices.recover(inspected=True)
            assert "gripper" in said, said
            devices.gripper.open()  # the release: it reaches the controller
            wait_for(lambda: not output(), "the stand-in's tool output low after open",
                     seen=output)
        finally:
            devices.close()


def test_a_recovery_with_the_link_up_leaves_the_grippers_link_alone():
    """A protective stop drops no link: the recovery must not connect the gripper's live link again.
    It did, after every fault, and raced the controller's release of the old link's registers (CI:
    "One of the RTDE input registers are already in use", Recover refused)."""
    with standin() as ur, realtime_threads():
        devices = RigDevices(RigSpec(config=rig_config(ur.host), scenario=Scenario.PERTURBED))
        try:
            def output() -> bool:
                return bool(ur.control("state")["tool_outputs"] >> TOOL_OUTPUT & 1)

            devices.gripper.close()
            wait_for(output, "the stand-in's tool output high after close", seen=output)
            assert ur.control("protective_stop")["ok"]
            wait_for(lambda: devices.connected.state is ArmState.FAULT, "the arm to see the protective stop",
                     seen=lambda: devices.connected.state)
            said = devices.recover(inspected=True)
            assert "protective stop" in said and "gripper" not in said, said
            devices.gripper.open()  # the same link still reaches the controller
            wait_for(lambda: not output(), "the stand-in's tool output low after open",
                     seen=output)
        finally:
            devices.close()
