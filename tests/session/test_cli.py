"""What ``serve`` and ``run-session`` share on their command lines (``app/session/cli.py``)."""

from __future__ import annotations

import argparse

import pytest

from app.session.cli import add_rig_arguments, rehearsed_hand
from app.session.config import LabConfig
from robot_io.errors import ConfigError

NATNET = {"kind": "natnet", "natnet_server": "192.168.1.20", "natnet_rigid_body": "hand",
          "units_to_m": 1.0}


@pytest.mark.parametrize(("hand_source", "flags", "rehearsed"), [
    ({}, [], "lsl"),  # a simulated hand: the rehearsal's own default
    ({"kind": "udp"}, [], "udp"),  # the lab's tracker protocol
    (NATNET, [], "natnet"),
    (NATNET, ["--rehearse-hand", "lsl"], "lsl"),  # said on the command line
])
def test_a_rehearsal_plays_the_hand_on_the_labs_tracker_protocol_unless_told(hand_source, flags,
                                                                                rehearsed):
    parser = argparse.ArgumentParser()
    add_rig_arguments(parser)
    lab = LabConfig.model_validate({"hand_source": hand_source})
    assert rehearsed_hand(parser.parse_args(["--rehearse", *flags]), lab) == rehearsed


VICON = {"kind": "vicon", "vicon_server": "192.168.1.30", "vicon_subject": "hand",
         "vicon_segment": "hand"}


def test_a_vicon_lab_rehearses_only_on_the_protocol_it_names():
    """No stand-in speaks Vicon's DataStream: a rehearsal on another protocol is said, never
    chosen for the lab."""
    parser = argparse.ArgumentParser()
    add_rig_arguments(parser)
    lab = LabConfig.model_validate({"hand_source": VICON})
    with pytest.raises(ConfigError, match=r'--rehearse cannot play the hand on Vicon\'s DataStream '
                                          r'\(\[hand_source\] kind = "vicon"\).* --rehearse-hand lsl'):
        rehearsed_hand(parser.parse_args(["--rehearse"]), lab)
    assert rehearsed_hand(parser.parse_args(["--rehearse", "--rehearse-hand", "udp"]), lab) == "udp"
