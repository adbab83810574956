"""What ``serve`` and ``run-session`` share on their command lines (``app/session/cli.py``)."""

from __future__ import annotations

import argparse

import pytest

from app.session.cli import add_rig_arguments, rehearsed_hand
from app.session.config import LabConfig

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
