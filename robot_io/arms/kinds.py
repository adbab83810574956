"""``[arm] kind``: the arms the rig can drive, each registered once in :data:`ARMS` (the pattern of
:mod:`robot_io.kinds`): its model, in its arm's module, has its own keys and says how the rig opens
it (connected once, or made anew each trial when it is simulated), its controller's own stop, and
how ``handover check-devices`` checks it. A second arm is one module (the arm and its
:class:`~robot_io.arms.arm.ArmKind`) and its name here."""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeAlias

from robot_io.arms.arm import ArmKind
from robot_io.arms.mock_arm import MockArmKind
from robot_io.arms.ur_arm import URArmKind
from robot_io.kinds import Kinds

#: Every kind of arm, by ``[arm] kind``: the one place a new kind is registered.
ARMS: Kinds[ArmKind] = Kinds("arm", "mock", MockArmKind, URArmKind)

if TYPE_CHECKING:
    #: To the type checker, a table of any kind: the field's type is made at run time.
    ArmConfig: TypeAlias = ArmKind
else:
    #: ``[arm]``: one of :data:`ARMS`, chosen by ``kind``.
    ArmConfig = ARMS.field(ArmKind)
