"""The dashboard's Devices panel says what the tracked hand's link went through: `handover serve`
with the mock arm and a NatNet hand source reading a stand-in Motive of the test's own (a port of
its own on 127.0.0.1), in headless Chromium. A truncated frame is dropped and counted; Motive closed
and started again on its port is connected again, and the panel says so."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from support.browser import chromium, open_page, open_participant, serve, shot, what_it_showed
from support.natnet import HAND, OBJECT, motive, natnet_toml, to_tracker_m
from support.waiting import wait_for

from robot_io.standins.natnet import pose_at

pytestmark = [pytest.mark.browser, pytest.mark.slow]

SHOTS = Path(os.environ.get("HANDOVER_SHOTS", "/tmp/links-shots"))
A = (0.55, 0.05, 0.30)  # robot base [m]


def poses():
    return {HAND.id: pose_at(to_tracker_m(A)), OBJECT.id: pose_at(to_tracker_m((0.4, -0.2, 0.45)))}


def test_the_devices_panel_says_what_the_hand_link_went_through(tmp_path: Path) -> None:
    """Slow (~30 s in a loaded full run): a ``serve`` that opens a participant (its learner's
    forkserver imports torch) and the dashboard's page in Chromium, then Motive's link dropped,
    lost and made again; the link's own timers take a second or two of it (LINK_STALL_S,
    RECONNECT_TIMEOUT_S)."""
    # Motive's threads under SCHED_FIFO: on the normal policy, in a full run on a slow machine, the
    # sender paused 0.5 s twice more and Devices said "link lost 3×" where the test loses it once
    with motive(poses, realtime=True) as server:
        port = server.address[1]
        with serve(tmp_path, tables=natnet_toml(server)) as served, chromium() as browser:
            dashboard = open_page(browser, served.dashboard_url, size=(1400, 900))
            open_participant(dashboard, "N01")

            def devices() -> str:
                text = dashboard.inner_text("body")
                return text[text.find("hand:"):][:300]

            wait_for(lambda: "NatNet rigid body 'hand'" in devices(), "the NatNet hand in Devices",
                     seen=lambda: what_it_showed(dashboard))
            server.send_truncated_frame()
            wait_for(lambda: "1 unreadable packet dropped" in devices(),
                     "the dropped frame counted in Devices", seen=devices)
            shot(dashboard, SHOTS, "hand-link-dropped")
            server.close()  # Motive is gone ...
            wait_for(lambda: "link lost at" in devices(), "the lost link in Devices", seen=devices)
            shot(dashboard, SHOTS, "hand-link-lost")
            with motive(poses, port=port, realtime=True):  # ... and back on its port
                shown = wait_for(lambda: re.search(r"link lost 1× and back, the last time after "
                                                   r"\d+\.\d s", devices()),
                                 "the link back in Devices", seen=devices)
                shot(dashboard, SHOTS, "hand-link-back")
    assert "1 unreadable packet dropped; link lost 1× and back" in shown.string
