"""``[gripper] kind``: the grippers the rig can drive, each registered once in :data:`GRIPPERS` (the
pattern of :mod:`robot_io.kinds`): its model, in its gripper's module, has its own keys and says how
the rig opens it, how the devices' report names it and how ``handover check-devices`` checks it
without moving it or switching anything."""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeAlias

from robot_io.grippers.gripper import GripperKind, NoGripperKind, ToolOutputKind
from robot_io.grippers.robotiq import RobotiqSocketKind
from robot_io.kinds import Kinds

#: Every kind of gripper, by ``[gripper] kind``: the one place a new kind is registered.
GRIPPERS: Kinds[GripperKind] = Kinds("gripper", "none", NoGripperKind, ToolOutputKind,
                                     RobotiqSocketKind)

if TYPE_CHECKING:
    #: To the type checker, a table of any kind: the field's type is made at run time.
    GripperConfig: TypeAlias = GripperKind
else:
    #: ``[gripper]``: one of :data:`GRIPPERS`, chosen by ``kind``.
    GripperConfig = GRIPPERS.field(GripperKind)
