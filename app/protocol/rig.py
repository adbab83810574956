"""The rig a session runs on, as its configuration names it: a resume on a different rig needs the
experimenter's confirmation (app/session/opening.py)."""

from __future__ import annotations

from robot_io.arms.kinds import ARMS
from robot_io.config import ControllerConfig
from robot_io.grippers.kinds import GRIPPERS
from robot_io.hands.config import HAND_SOURCES
from robot_io.kinds import Kinds

#: The tables of the configuration that name the devices (the rig): a resume on a different rig
#: needs the experimenter's confirmation.
RIG_TABLES = ("arm", "ur", "hand_source", "gripper")
#: The rig tables with one table per kind of device (robot_io.kinds).
KINDED: dict[str, Kinds] = {"arm": ARMS, "hand_source": HAND_SOURCES, "gripper": GRIPPERS}


def rig_of(config: dict) -> dict:
    """The rig tables of a configuration or of a recorded rig (as JSON). The ``[ur]`` table is part
    of a rig only when its arm is a UR: a mock arm's says nothing about the rig (and a session
    recorded before ``[ur] host`` lost its default holds 192.168.1.10 there). A setting a recorded
    table lacks did not exist when it was recorded: the session ran as its default does (e.g. the
    NatNet and Robotiq settings), so a resume on the default is no rig change. A device table is
    compared on its kind's keys: one recorded before each kind had a table of its own has every
    kind's keys."""
    defaults = ControllerConfig().model_dump(mode="json")
    rig = {table: None if config.get(table) is None else {**defaults[table], **config[table]}
           for table in RIG_TABLES}
    if (rig["arm"] or {}).get("kind") != "ur":
        rig["ur"] = None
    for table, kinds in KINDED.items():
        recorded = rig[table]
        if recorded is not None:
            kind = recorded.get("kind", kinds.default)
            rig[table] = kinds.own_keys({**(kinds.defaults(kind) if kind in kinds else {}), **recorded})
    return rig
