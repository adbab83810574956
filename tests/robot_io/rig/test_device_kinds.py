"""Each device kind is registered once, the same way for hands, arms and grippers (robot_io.kinds): its
model has its own keys and says what opens it. A second arm is one module and one line in the
registry: a throwaway arm kind, registered by a fixture, is read from the configuration with its own
key, refused keys of another kind, connected once by the rig, named in the devices' report and by
``check-devices``, and runs a whole handover cycle; after the test it is gone."""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from typing import Literal

import numpy as np
import pytest
from pydantic import Field, ValidationError

from robot_io.arms.arm import ArmKind, ArmSettings
from robot_io.arms.kinds import ARMS
from robot_io.arms.mock_arm import MockArm
from robot_io.clock import RealClock
from robot_io.config import ControllerConfig
from robot_io.control.cycle import Gates, run_cycle
from robot_io.control.loop import Outcome
from robot_io.control.stages import Stage
from robot_io.devices import check_devices
from robot_io.errors import explain
from robot_io.grippers.kinds import GRIPPERS
from robot_io.hands.config import HAND_SOURCES
from robot_io.hands.simulated_hand import Scenario
from robot_io.hands.tracked_hand import TrackedHand
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import RigSpec
from robot_io.theta import Theta

#: Where the bench arm's TCP is when it connects [m].
BENCH_REST = np.array([0.4, -0.3, 0.4])


def test_every_gripper_kind_is_registered_and_named_in_the_report():
    config = ControllerConfig.model_validate({"arm": {"kind": "ur"}, "ur": {"host": "192.168.1.10"}})
    described = {kind: GRIPPERS.validate({"kind": kind}).describe(config.controller_host)
                 for kind in GRIPPERS}
    assert described == {"none": "no gripper", "tool_output": "tool digital output 0",
                         "robotiq_socket": "Robotiq 2F-85 on 192.168.1.10:63352"}


def test_every_tracker_kind_names_a_tracked_hand_that_says_its_protocol():
    readers = {kind: model.reader for kind, model in HAND_SOURCES.items()}
    assert readers.pop("simulated") is None
    for kind, reader in readers.items():
        module, name = reader.split(":")
        source = getattr(importlib.import_module(module), name)
        assert issubclass(source, TrackedHand) and source.PROTOCOL, kind
        assert source.describe is not TrackedHand.describe, kind


@pytest.mark.parametrize(("table", "key", "message"), [
    ("gripper", {"kind": "none", "speed": 100},
     '[gripper] speed is a key of kind = "robotiq_socket", not of kind = "none"'),
    ("gripper", {"kind": "robotiq_socket", "host": "10.0.0.8", "tool_output": 1},
     '[gripper] tool_output is a key of kind = "tool_output", not of kind = "robotiq_socket"'),
    ("gripper", {"kind": "suction"},
     "[gripper] kind = 'suction' is no gripper; the kinds are \"none\", \"tool_output\", "
     '"robotiq_socket"'),
    ("arm", {"kind": "ur5"}, "[arm] kind = 'ur5' is no arm; the kinds are \"mock\", \"ur\""),
])
def test_a_key_or_kind_that_does_not_belong_is_refused_naming_it(table, key, message):
    with pytest.raises(ValidationError) as refused:
        ControllerConfig.model_validate({table: key, "ur": {"host": "10.0.0.7"}})
    assert explain(refused.value).startswith(message)


def test_a_table_of_every_kind_s_keys_still_loads_with_its_own_keys():
    """A [gripper] table written when one table held every kind's keys: the other kinds' defaults
    say nothing, and the gripper is read (and written) with its own keys."""
    flat = {"kind": "tool_output", "tool_output": 1, "open_level": False, "host": None, "port": 63352,
            "speed": 255, "force": 50, "open_position": 0, "closed_position": 255,
            "move_timeout_s": 5.0, "reply_timeout_s": 1.0}
    config = ControllerConfig.model_validate({"gripper": flat, "arm": {"kind": "ur"},
                                              "ur": {"host": "10.0.0.7"}})
    assert config.model_dump(mode="json")["gripper"] == {"kind": "tool_output", "tool_output": 1,
                                                         "open_level": False}
    assert GRIPPERS.own_keys(flat) == config.model_dump(mode="json")["gripper"]


class BenchArm(MockArm):
    """A throwaway real arm: the kinematic mock on the wall clock, connected once per rig."""

    rate_hz = 125
    links_restored = 0
    version = "bench 1.0"

    def __init__(self, port: int) -> None:
        super().__init__(RealClock(self.rate_hz), BENCH_REST)
        self.port, self.closed = port, False

    def describe(self) -> str:
        return f"bench arm on port {self.port}, {self.rate_hz} Hz"

    def close(self) -> None:
        self.closed = True


class BenchArmKind(ArmKind):
    """``[arm] kind = "bench"``, with a key of its own: a second arm as a lab adds one."""

    kind: Literal["bench"]
    bench_port: int = Field(7000, ge=1, le=65535, description="the bench arm's port")

    def connect(self, settings: ArmSettings) -> BenchArm:
        return BenchArm(self.bench_port)


@pytest.fixture
def bench_arm() -> Iterator[type[BenchArmKind]]:
    """The bench arm registered, for this test only (one line: the registry's extension point)."""
    with ARMS.added(BenchArmKind) as kind:
        yield kind
    assert "bench" not in ARMS
    with pytest.raises(ValidationError, match="is no arm"):
        ControllerConfig.model_validate({"arm": {"kind": "bench"}})


def test_a_second_arm_is_one_module_and_one_registry_line(bench_arm):
    config = ControllerConfig.model_validate({"arm": {"kind": "bench", "bench_port": 7001},
                                              "release": {"timeout_s": 0.5}})
    assert isinstance(config.arm, bench_arm) and config.arm.bench_port == 7001
    assert config.model_dump(mode="json")["arm"] == {"kind": "bench", "bench_port": 7001}
    assert ControllerConfig.model_validate(config.model_dump(mode="json")) == config
    with pytest.raises(ValidationError) as refused:
        ControllerConfig.model_validate({"arm": {"kind": "mock", "bench_port": 7001}})
    assert explain(refused.value).startswith(
        '[arm] bench_port is a key of kind = "bench", not of kind = "mock"')

    lines, ok = check_devices(config, listen_s=0.0)
    assert ok and lines[0] == (f"arm: bench arm on port 7001, 125 Hz, TCP at "
                               f"{np.round(BENCH_REST, 3).tolist()} m, idle")
    devices = RigDevices(RigSpec(config=config, scenario=Scenario.STRAIGHTFORWARD, realtime=True))
    try:
        report = devices.report()
        assert (report.arm, report.arm_detail, report.polyscope_version, report.rate_hz) == (
            "bench", "bench arm on port 7001, 125 Hz", "bench 1.0", 125)
        trial = devices.for_trial(hand_seed=3)
        assert trial.arm is devices.connected and isinstance(trial.arm, BenchArm)
        stages: list[str] = []
        record = run_cycle(devices.config, Theta(a=5.0, delta=-0.2, k=5.0), trial,
                           Gates.automatic(), lambda stage, t: stages.append(stage))
    finally:
        devices.close()
    # nobody pulls on the bench: the object is held out, not taken, and the arm goes back to R
    assert record.summary.outcome is Outcome.NOT_TAKEN, record.summary.reason
    assert stages[-4:] == [Stage.HOLD, Stage.NOT_TAKEN, Stage.RETRACT, Stage.DONE]
    assert trial.arm.commands_received > 100 and trial.arm.closed
    np.testing.assert_allclose(trial.arm.read_pose(), config.scene.point("robot_start"))
