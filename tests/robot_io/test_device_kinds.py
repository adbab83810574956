"""Each device kind the configuration accepts is registered once, with what opens it: every
``[hand_source] kind`` has its model (a tracker's names its reader), every ``[gripper] kind`` its
entry in robot_io.grippers.kinds; and the registers hold no kind the configuration refuses."""

from __future__ import annotations

import importlib
from typing import get_args

from robot_io.config import ControllerConfig, GripperConfig
from robot_io.grippers.kinds import GRIPPERS
from robot_io.hands.config import HAND_SOURCES
from robot_io.hands.tracked_hand import TrackedHand


def test_every_gripper_kind_of_the_configuration_is_registered_and_named_in_the_report():
    assert set(GRIPPERS) == set(get_args(GripperConfig.model_fields["kind"].annotation))
    config = ControllerConfig.model_validate({"arm": {"kind": "ur"}, "ur": {"host": "192.168.1.10"}})
    described = {kind: GRIPPERS[kind].describe(config.model_copy(update={
        "gripper": GripperConfig(kind=kind)})) for kind in GRIPPERS}
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
