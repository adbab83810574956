"""``[ur]``: the UR5 over RTDE (``robot_io.arms.ur_arm``), the settings of ``[arm] kind = "ur"``
(docs/hardware.md)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from robot_io.bounds import Frozen, in_range


class URConfig(Frozen):
    """The UR5 over RTDE (``robot_io.arms.ur_arm``); see ``docs/hardware.md``."""

    host: str | None = Field(
        None, description="controller address, required by [arm] kind = \"ur\"; never assumed "
                          "(a stand-in: 127.0.0.x)")
    servo_lookahead_s: float = Field(
        0.1, ge=0.03, le=0.2, description="servoL lookahead time [s] (ur_rtde's range [0.03, 0.2])")
    servo_gain: float = Field(300.0, ge=100, le=2000,
                              description="servoL proportional gain (ur_rtde's range [100, 2000])")
    watchdog_hz: float = Field(
        10.0, gt=0, le=125,
        description="controller watchdog: the program stops if no target comes for 1/watchdog_hz s; "
                    "10 Hz tolerates Python jitter (50 Hz tripped on a 31 ms stall)")
    move_speed: float = Field(0.25, gt=0, le=0.5, description="moveL to the start pose: speed [m/s]")
    move_acceleration: float = Field(0.5, gt=0, le=1.2, description="moveL acceleration [m/s²]")
    max_move_distance: float = Field(
        0.6, gt=0, le=1.0, description="move_to refuses a start pose farther than this from the TCP [m]")
    stop_deceleration: float = Field(5.0, gt=0, le=10,
                                     description="servoStop deceleration at the end of a trial [m/s²]")
    connect_timeout_s: Annotated[float, in_range(0, 120, "s")] = Field(
        10.0, description="give up connecting after this [s]")
    upper_range_registers: bool = Field(
        False, description="use RTDE registers 24–47 (when a fieldbus owns 0–23)")
