"""Replaying a stored trial in the dashboard's 3-D view, checked against the stored samples.

In process: a real :class:`SessionRunner` (engine, store, rig and learner processes) behind the real
servers of ``handover serve``; the dashboard in headless Chromium. One trial runs (the simulated
participant places it), then the experimenter picks it under "Replay a stored trial" and presses
Replay: every position the server sends for the robot's TCP and the hand must be a stored sample's,
in recorded order, ending at the trial's last sample; the coupling plots end as the stored τ. The arm
is drawn as the UR5's kinematic links on the rehearsal rig (the stand-in UR reports joint angles):
every set of link points sent is the forward kinematics of a stored sample's joint angles, in order,
ending at the last; on the mock arm (no joint angles) as the stand-in arm. A trial that starts ends a
replay, and the store refuses a replay while a trial runs. Once that trial has ended, ``serve``'s close
(Ctrl-C) during a slow replay, with a second dashboard window open, sends nothing on a connection
viser has closed (its warning): the replay's thread has ended before the servers stop, and no page
is drawn once the session has closed (viser's stop closes every connection before it tells us of
one, and a window's close refreshes the others). Both warned before.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from support.browser import (
    TOKEN,
    chromium,
    click,
    open_folder,
    open_page,
    unlock_dashboard,
    wait_text,
    watch_client,
    what_it_showed,
)
from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe, busy_threads, ended, ready, run_trial
from support.waiting import CEILING_S, wait_for

from app.protocol.errors import RefusedAction
from app.session.config import LabConfig
from app.session.rehearsal import Rehearsal
from app.session.runner import SessionRunner
from app.ui.server import HandoverServers, ServeOptions
from robot_io.arms.ur_kinematics import link_points
from robot_io.hands.simulated_hand import Scenario
from session_store.sample_rows import stored_rows
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: the default release timeout (10 s): the replayed trial must be a completed one, also on a busy
#: machine where the simulated hand reaches H late
LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": SHORT_PROTOCOL})


def matches(point: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The indices of the stored rows equal to ``point`` (float32 on the wire)."""
    return np.flatnonzero(np.all(np.abs(rows - point) < 1e-5, axis=1))


class InOrder:
    """Positions shown one after another must be stored samples in recorded order: each frame's
    position matches a row at or after the previous frame's (a held-still position matches
    several rows; the earliest one that keeps the order is taken)."""

    def __init__(self, rows: np.ndarray, what: str) -> None:
        self.rows, self.what, self.index, self.indices = rows, what, 0, []

    def see(self, point: np.ndarray) -> None:
        found = matches(point, self.rows)
        later = found[found >= self.index]
        assert len(found), f"the {self.what} at {point} is not a stored sample"
        assert len(later), f"the {self.what} went back in time (stored at {found})"
        self.index = int(later[0])
        self.indices.append(self.index)


def drawn_joints(segments: np.ndarray) -> np.ndarray:
    """The joint positions (7 × 3, flattened) of the UR5's drawn links: each link's start, then the
    last link's end."""
    return np.concatenate([segments[:, 0], segments[-1:, 1]]).reshape(-1)


@pytest.mark.parametrize("rig", ["mock", pytest.param("rehearsal", marks=pytest.mark.standin)])
def test_a_stored_trial_replays_its_samples(tmp_path: Path, rig: str,
                                           recwarn: pytest.WarningsRecorder) -> None:
    """Slow (about a minute alone on the rehearsal rig): two trials on the wall clock (through the
    stand-in UR there), the replay, which streams every stored sample to Chromium at the recorded
    rate, and a second dashboard window."""
    rehearsal = Rehearsal(LAB) if rig == "rehearsal" else None
    # The rig process under SCHED_FIFO on either rig, as a lab runs it (support.browser.serve does
    # the same): on the normal policy beside a hog the mock rig wrote no sample for 0.5 s, the
    # backstop stopped it as it must, and the trial to replay was aborted.
    runner = SessionRunner(tmp_path / "study", LAB, rehearsal=rehearsal, realtime_priority=True)
    # port 0: any free port each; the dashboard's is read from its server below
    servers = HandoverServers(runner, ServeOptions(tablet_port=0, dashboard_port=0, token=TOKEN))
    probe = Probe(runner)
    closed = False
    try:
        runner.set_auto(True)  # the simulated participant places it (no tablet needed: simulated rig)
        runner.open("P01", Scenario.PERTURBED)
        trial = run_trial(runner, probe)  # repeated if the machine starved it
        assert trial.outcome.value == "completed", f"trial {trial.trial_index}: {trial.reason}"
        probe.wait(ready, what="the next θ", timeout=READY_CEILING_S)
        store = ParticipantStore.open(runner.study, "P01")
        try:
            stored = stored_rows(store.samples(trial.trial_index))
        finally:
            store.close()
        keep = np.isfinite(stored["t"])
        measured, hand, tau = stored["measured"][keep], stored["hand"][keep], stored["tau"][keep]
        q = stored["q"][keep]
        assert np.all(np.isfinite(q)) if rig == "rehearsal" else np.all(np.isnan(q))
        joints = link_points(q).reshape(len(q), -1)  # FK of the stored joint angles, (n, 21)
        duration = float(stored["t"][keep][-1] - stored["t"][keep][0])

        with chromium() as browser:
            dashboard = open_page(browser, f"http://127.0.0.1:{servers.dashboard_server.get_port()}",
                                  size=(1366, 768))
            unlock_dashboard(dashboard)
            [client] = servers.dashboard.clients.values()
            watch_client(dashboard, client.client)
            open_folder(dashboard, "Replay a stored trial")
            wait_for(lambda: client.replay_trial.value.startswith(f"trial {trial.trial_index} "),
                     f"trial {trial.trial_index} offered for replay",
                     seen=lambda: client.replay_trial.options)
            began = time.monotonic()
            click(dashboard, "Replay")
            tcp, held = InOrder(measured, "TCP"), InOrder(hand, "hand")
            arm = InOrder(joints, "UR5's joints")
            live = client.live
            wait_for(lambda: client.replay is not None and client.replay.frames > 0,
                     "the replay's first frame drawn", poll=0.005,
                     seen=lambda: f"status {client.replay_status.content!r}; {what_it_showed(dashboard)}; "
                          f"threads in the project's code:\n{busy_threads()}")
            # Sampling what the server draws while the replay runs (each sample is checked): a poll
            # of the live view, not a wait; a busy machine samples fewer frames (≥ 10 needed of a
            # trial's seconds at 20 frames/s).
            while client.replay.running:
                tcp.see(np.asarray(live.tcp.position))
                held.see(np.asarray(live.hand.position))
                if rig == "rehearsal":
                    arm.see(drawn_joints(np.asarray(live.ur5.points)))
                time.sleep(0.02)
            elapsed = time.monotonic() - began
            wait_text(dashboard, "replay finished")
            assert len(set(tcp.indices)) >= 10, "the replay did not move"
            assert len(measured) - 1 in matches(np.asarray(live.tcp.position), measured)
            assert np.allclose(live.plots["tau"].data[1], tau[np.isfinite(tau)])
            # the UR5 drawn from the joint angles where they were stored, the stand-in arm where not
            ur5 = rig == "rehearsal"
            assert (live.ur5.visible, live.links.visible, live.base.visible) == (ur5, not ur5, not ur5)
            if ur5:
                assert len(set(arm.indices)) >= 10, "the UR5 did not move"
                assert len(q) - 1 in matches(drawn_joints(np.asarray(live.ur5.points)), joints)
            # 1×: never faster than the trial itself. A lower bound on the wall time the replay
            # took: load only lengthens a replay, so this cannot go red on a busy machine.
            assert elapsed >= 0.9 * duration

            # A slower replay ends when a trial starts; the store refuses a replay during a trial.
            dashboard.locator("xpath=//*[normalize-space(text())='Speed']/following::input[1]").click()
            dashboard.get_by_role("option", name="0.25×").click()
            click(dashboard, "Replay")
            wait_text(dashboard, "replaying trial 1 at 0.25×")
            second = runner.start_trial().trial_index  # the simulated participant is on (mock arm)
            wait_text(dashboard, "replay ended: a trial started")
            with pytest.raises(RefusedAction, match="replay refused while a trial runs"):
                runner.trial_rows(trial.trial_index)

            # serve closed during a replay (Ctrl-C): the replay's thread, which draws on the page,
            # has ended before the servers stop; none draws on a connection viser has closed
            probe.wait(lambda v: ended(v, second) is not None, what=f"trial {second} ended",
                       timeout=CEILING_S + READY_CEILING_S)
            # a second window: the first one's disconnect at the close refreshes the others
            other = open_page(browser, f"http://127.0.0.1:{servers.dashboard_server.get_port()}",
                              size=(1366, 768))
            unlock_dashboard(other)
            wait_text(dashboard, "2 dashboard windows are open")
            click(dashboard, "Replay")
            wait_text(dashboard, "at 0.25×")
            replay = client.replay
            wait_for(lambda: replay.frames > 0, "the slow replay's first frame drawn",
                     seen=lambda: f"status {client.replay_status.content!r}")
            servers.close()
            closed = True
            assert not replay.running, "the replay's thread outlived serve's close"
        dead_writes = [str(w.message) for w in recwarn if "on a closed connection" in str(w.message)]
        assert not dead_writes, dead_writes
    finally:
        if not closed:
            servers.close()
