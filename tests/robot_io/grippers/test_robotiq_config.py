"""``[gripper] kind = "robotiq_socket"`` in the lab file: its address is never assumed, and each
value outside its range is refused naming the field and the range."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from app.session.config import LabConfig
from robot_io.config import ControllerConfig


def lab(**gripper) -> LabConfig:
    return LabConfig.model_validate({"gripper": {"kind": "robotiq_socket", **gripper}})


def test_the_urcap_address_is_the_gripper_host_else_the_ur_host_and_never_assumed():
    with pytest.raises(ValidationError, match=r"\[gripper\] host is not set and neither is \[ur\] host"):
        lab()
    on_ur = ControllerConfig.model_validate({"gripper": {"kind": "robotiq_socket"},
                                             "ur": {"host": "10.0.0.7"}})
    assert on_ur.gripper_host == "10.0.0.7" and on_ur.gripper.port == 63352
    own = lab(host="10.0.0.8").controller
    assert own.gripper_host == "10.0.0.8"


@pytest.mark.parametrize(("setting", "message"), [
    ({"port": 70000}, r"gripper\.port\n.*less than or equal to 65535"),
    ({"speed": 256}, r"gripper\.speed\n.*less than or equal to 255"),
    ({"force": -1}, r"gripper\.force\n.*greater than or equal to 0"),
    ({"open_position": 300}, r"gripper\.open_position\n.*less than or equal to 255"),
    ({"open_position": 200, "closed_position": 200},
     r"gripper\.closed_position = 200 must be above gripper\.open_position = 200"),
    ({"move_timeout_s": 0}, r"gripper\.move_timeout_s\n.*must be a finite number in \(0, 30\] s"),
    ({"reply_timeout_s": 11}, r"gripper\.reply_timeout_s\n.*must be a finite number in \(0, 10\] s"),
])
def test_a_value_outside_its_range_is_refused_naming_the_field_and_the_range(setting, message):
    with pytest.raises(ValidationError, match=message):
        lab(host="10.0.0.8", **setting)
