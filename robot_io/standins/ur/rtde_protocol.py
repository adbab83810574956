"""The RTDE wire protocol (version 2) as a UR controller serves it on port 30004.

Every message: ``uint16 size`` (header included), ``uint8 type``, payload; all big-endian. Types used:
``V`` request protocol version (payload uint16; reply uint8 accepted), ``v`` controller version (reply
4 × uint32: major, minor, bugfix, build), ``O`` setup outputs (payload double frequency + comma-separated
names; reply uint8 recipe id + comma-separated types, ``NOT_FOUND`` for unknown names), ``I`` setup
inputs (payload names; reply uint8 recipe id + types, ``IN_USE`` for inputs another client owns), ``S``
start and ``P`` pause (reply uint8 accepted), ``U`` data package (uint8 recipe id + packed values),
``M`` text message.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
SETUP_OUTPUTS = ord("O")
SETUP_INPUTS = ord("I")
START = ord("S")
PAUSE = ord("P")

HEADER = struct.Struct(">HB")

#: struct format of each RTDE data type.
FORMATS = {
    "BOOL": "?", "UINT8": "B", "UINT32": "I", "UINT64": "Q", "INT32": "i", "DOUBLE": "d",
    "VECTOR3D": "3d", "VECTOR6D": "6d", "VECTOR6INT32": "6i", "VECTOR6UINT32": "6I",
}

_VECTOR6D = ("target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
             "actual_qd", "actual_current", "actual_current_window", "joint_control_output",
             "actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose",
             "target_TCP_speed", "joint_temperatures", "actual_joint_voltage", "ft_raw_wrench",
             "payload_inertia", "joint_position_deviation_ratio", "target_current_window")
_DOUBLE = ("timestamp", "actual_execution_time", "speed_scaling", "target_speed_fraction",
           "actual_momentum", "actual_main_voltage", "actual_robot_voltage", "actual_robot_current",
           "standard_analog_input0", "standard_analog_input1", "standard_analog_output0",
           "standard_analog_output1", "io_current", "tool_analog_input0", "tool_analog_input1",
           "tool_output_current", "tool_temperature", "tcp_force_scalar", "payload",
           "euromap67_24V_voltage", "euromap67_24V_current", "actual_robot_energy_consumed",
           "actual_robot_braking_energy_dissipated")
_INT32 = ("robot_mode", "safety_mode", "safety_status", "tool_output_voltage")
_UINT32 = ("runtime_state", "robot_status_bits", "safety_status_bits", "analog_io_types", "tool_mode",
           "tool_analog_input_types", "euromap67_input_bits", "euromap67_output_bits",
           "output_bit_registers0_to_31", "output_bit_registers32_to_63", "script_control_line",
           "input_bit_registers0_to_31", "input_bit_registers32_to_63")
_UINT64 = ("actual_digital_input_bits", "actual_digital_output_bits")
_UINT8 = ("tool_output_mode", "tool_digital_output0_mode", "tool_digital_output1_mode")
_VECTOR3D = ("actual_tool_accelerometer", "elbow_position", "elbow_velocity", "payload_cog")


def _registers(direction: str) -> dict[str, str]:
    names = {f"{direction}_int_register_{i}": "INT32" for i in range(48)}
    names |= {f"{direction}_double_register_{i}": "DOUBLE" for i in range(48)}
    names |= {f"{direction}_bit_register_{i}": "BOOL" for i in range(64, 128)}
    return names


#: Variables a client may subscribe to in an output recipe.
OUTPUT_TYPES: dict[str, str] = (
    {name: "VECTOR6D" for name in _VECTOR6D} | {name: "DOUBLE" for name in _DOUBLE}
    | {name: "INT32" for name in _INT32} | {name: "UINT32" for name in _UINT32}
    | {name: "UINT64" for name in _UINT64} | {name: "UINT8" for name in _UINT8}
    | {name: "VECTOR3D" for name in _VECTOR3D} | {"joint_mode": "VECTOR6INT32"}
    | _registers("output") | _registers("input")
)

#: Variables a client may write in an input recipe.
INPUT_TYPES: dict[str, str] = {
    "speed_slider_mask": "UINT32", "speed_slider_fraction": "DOUBLE",
    "standard_digital_output_mask": "UINT8", "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8", "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8", "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8", "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE", "standard_analog_output_1": "DOUBLE",
    "input_bit_registers0_to_31": "UINT32", "input_bit_registers32_to_63": "UINT32",
    "external_force_torque": "VECTOR6D",
} | _registers("input")


def frame(message_type: int, payload: bytes = b"") -> bytes:
    """One message: header + payload."""
    return HEADER.pack(HEADER.size + len(payload), message_type) + payload


def recipe_format(types: Sequence[str]) -> struct.Struct:
    """The packed layout of a recipe's values (after the recipe id)."""
    return struct.Struct(">" + "".join(FORMATS[t] for t in types))


def flatten(values: Sequence[object]) -> list[object]:
    """Recipe values with vectors spread out, ready for ``struct.pack``."""
    flat: list[object] = []
    for value in values:
        if isinstance(value, (list, tuple)):
            flat.extend(value)
        else:
            flat.append(value)
    return flat


def group(types: Sequence[str], flat: Sequence[object]) -> list[object]:
    """The inverse of :func:`flatten`: vectors gathered back into lists."""
    values, i = [], 0
    for t in types:
        width = int(FORMATS[t][0]) if FORMATS[t][0].isdigit() else 1
        values.append(list(flat[i:i + width]) if width > 1 else flat[i])
        i += width
    return values
