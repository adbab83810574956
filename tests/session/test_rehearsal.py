"""The study on the rehearsal rig — the real code path with no hardware: the stand-in UR controller
over ur_rtde, the simulated participant's hand on LSL, the tool-output gripper and the force release.
The paper's whole session through ``handover run-session --rehearse``, then one fault at a time."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys

import numpy as np
import pytest
import pyxdf
from support.engine import BRIEF_PROTOCOL, SHORT_PROTOCOL, protocol_toml
from support.runner import READY_CEILING_S, Probe, ended, run_trial
from support.waiting import CEILING_S, wait_for

from app.protocol.errors import RefusedAction
from app.session.config import LabConfig
from app.session.faults import StagedFault
from app.session.rehearsal import Rehearsal
from app.session.runner import SessionRunner
from robot_io.arms.ur_kinematics import forward
from robot_io.control.stages import PAPER_CYCLE, Stage
from robot_io.hands.simulated_hand import Scenario
from session_store.recordings import recordings_of
from session_store.sample_rows import stored_rows
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.slow, pytest.mark.soak, pytest.mark.standin]


def handover(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


def test_run_session_rehearse_completes_a_session_through_the_standin(tmp_path):
    """`run-session --rehearse` through ur_rtde, LSL and the tool output of the stand-in, on the
    briefest protocol that ends a session (2 initial interactions, their comparison, the learned
    best, the questionnaire): every trial is the same cycle on the rig, whatever its phase. The
    paper's 34 were run here until the suite had to fit in 12 minutes (5 min of real time per run):
    the protocol's phases are the engine's (tests/protocol/test_session_full.py), they run end to
    end through run-session in tests/protocol/test_resume_exact.py (uninterrupted and killed), and
    through serve --rehearse in tests/ui/test_rig_browser.py (three handovers placed by touch)."""
    config = tmp_path / "lab.toml"
    config.write_text(f"[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}")
    done = handover("run-session", "--study", str(tmp_path), "--participant", "R01", "--scenario",
                    "straightforward", "--seed", "5", "--auto", "--rehearse",
                    "--config", str(config), "--json", "--no-progress")
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    n = 3  # BRIEF_PROTOCOL: 2 initial, 1 best
    assert summary["completed"] == n and "PolyScope 3.15" in summary["rig"]
    assert "LSL stream" in summary["hand"]
    with sqlite3.connect(tmp_path / "R01.sqlite") as db:
        db.row_factory = sqlite3.Row
        completed = db.execute("SELECT * FROM trials WHERE outcome = 'completed'").fetchall()
        stages = db.execute("SELECT payload FROM events WHERE kind = 'trial_stage'").fetchall()
        released_pull = {row["trial_index"]: row["pull"] for row in db.execute(
            "SELECT trial_index, max(pull) AS pull FROM samples WHERE stage = 3 GROUP BY trial_index")}
        sampled = {row[0] for row in db.execute("SELECT DISTINCT trial_index FROM samples")}
    assert len(completed) == n
    for trial in completed:
        assert trial["go_at"] is not None, trial["trial_index"]
        assert trial["retract_end_s"] is not None, (dict(trial), done.stderr[-3000:])
        assert 0 < trial["robot_arrival_s"] <= trial["hold_s"] < trial["release_s"] \
            < trial["retract_end_s"]
        assert trial["hand_arrival_s"] is not None
        assert trial["peak_pull_n"] >= 10.0  # released by force: the pull passed the threshold
        assert released_pull[trial["trial_index"]] >= 10.0
        assert trial["trial_index"] in sampled
    seen = [json.loads(row[0])["stage"] for row in stages]
    assert seen.count("release") >= n and seen.count("done") >= n
    # what the stand-in controller itself saw: the tool output switched, the robot went back to R
    stand_in = summary["rehearsal"]
    assert stand_in["gripper_opened"] >= n and stand_in["gripper_closed"] >= n
    assert stand_in["moves_to_R"] >= 2 * n  # prepare and retract, every trial
    assert stand_in["tcp_to_R_m"] < 1e-3


def test_a_rehearsal_records_through_the_stand_in_labrecorder_when_the_lab_drives_its_own(tmp_path):
    """A lab whose session drives its LabRecorder over the remote control, on another machine,
    rehearses with `run-session --rehearse`: the rehearsal starts the stand-in LabRecorder on
    loopback instead, and the study folder gets the run's file with the session's two streams and
    the rehearsal's hand, a Go marker for every stored trial. A whole rehearsed session on the
    wall clock (~25 s alone), and the file closed after it."""
    name = f"rcs_{os.getpid()}_{tmp_path.name}"
    config = tmp_path / "lab.toml"
    config.write_text(f"[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}\n"
                      f'[record]\nlsl_outlets = true\nlsl_name = "{name}"\n'
                      '[recording]\nkind = "labrecorder_rcs"\nrcs_host = "recorder.invalid"\n'
                      "rcs_port = 1\n")
    done = handover("run-session", "--study", str(tmp_path), "--participant", "R01", "--scenario",
                    "straightforward", "--seed", "6", "--auto", "--rehearse",
                    "--config", str(config), "--json", "--no-progress")
    assert done.returncode == 0, done.stderr[-3000:]
    files = recordings_of(tmp_path, "R01")
    assert [f.name for f in files] == ["sub-R01_ses-01_task-handover_run-001_beh.xdf"], files
    streams = {s["info"]["name"][0]: s for s in pyxdf.load_xdf(str(files[0]))[0]}
    hand = [n for n, s in streams.items() if s["info"]["type"][0] == "Mocap"]
    assert set(streams) == {f"{name}-markers", f"{name}-robot", *hand} and len(hand) == 1, streams
    assert hand[0].startswith("handover-rehearsal-") and len(streams[hand[0]]["time_stamps"]) > 100
    markers = [json.loads(text[0]) for text in streams[f"{name}-markers"]["time_series"]]
    with sqlite3.connect(tmp_path / "R01.sqlite") as db:  # a trial the machine ended before Go has none
        with_go = [row[0] for row in db.execute(
            "SELECT trial_index FROM trials WHERE go_at IS NOT NULL ORDER BY trial_index")]
    assert sorted(m["trial"] for m in markers if m["event"] == "go") == with_go and len(with_go) >= 3


def moving(runner: SessionRunner) -> bool:
    """The reach runs and the stand-in controller reports the TCP moving (above the hold's settle
    speed, 0.02 m/s)."""
    return runner.view.stage == Stage.REACH and runner.rehearsal.control("state")["speed"] > 0.02


def stopped(state: dict) -> dict | None:
    """The stand-in controller's ``state`` if no program runs and the TCP stands still."""
    return state if state["program"] is None and state["speed"] < 1e-3 else None


def start_until(runner: SessionRunner, probe: Probe, stage: Stage) -> None:
    probe.wait(lambda v: v.step is not None and v.step.value == "ready", what="ready to start",
               timeout=READY_CEILING_S)
    runner.start_trial()
    probe.wait(lambda v: v.stage == stage, what=f"stage {stage}")


def test_every_rehearsed_sample_carries_joint_angles_and_coupling_signals(rehearsed):
    """The stand-in UR reports actual_q; the rig records it with the TCP of the same state package,
    and the store keeps it: the UR5's FK of every stored q is the stored TCP position within 1 mm.
    The coupling signals of the reach are stored through the hold's compliance wrapper, and obey
    eqs. (5) and (8): τ = τ0 (1 + C_t), C_t = k σ_d σ_j."""
    runner, probe = rehearsed
    runner.open("J01", Scenario.PERTURBED, seed=7)
    trial = run_trial(runner, probe)  # repeated if the machine starved it
    assert trial.outcome.value == "completed", trial.reason
    store = ParticipantStore.open(runner.study, "J01")
    try:
        rows = stored_rows(store.samples(trial.trial_index))
    finally:
        store.close()
    keep = np.isfinite(rows["t"])
    q, measured = rows["q"][keep], rows["measured"][keep]
    assert len(q) > 100 and np.all(np.isfinite(q))
    assert np.ptp(q, axis=0).max() > 0.1  # the arm moved its joints
    error = np.linalg.norm(forward(q)[:, :3, 3] - measured, axis=1)
    assert error.max() < 1e-3, f"FK(q) is {error.max() * 1e3:.3f} mm from the recorded TCP"
    reach = keep & (rows["stage"] == PAPER_CYCLE.sample_code(Stage.REACH))
    c_t = rows["c_t"][reach]
    assert reach.sum() > 100 and np.isfinite(c_t).mean() > 0.95, "coupling signals not recorded"
    ok = np.isfinite(c_t)
    np.testing.assert_allclose(rows["tau"][reach][ok],
                               runner.lab.controller.dmp.tau0 * (1 + c_t[ok]))
    np.testing.assert_allclose(c_t[ok], trial.theta_k * rows["sigma_d"][reach][ok]
                               * rows["sigma_j"][reach][ok])


def test_tracker_lost_during_reach_holds_the_arm_aborts_and_repeats_the_trial(rehearsed):
    """The staged loss aborts the reach and the arm holds short of H; the repeated trial started
    while the marker is still hidden waits at ready, saying why, and runs once the tracker sees the
    hand again."""
    runner, probe = rehearsed
    runner.open("F01", Scenario.STRAIGHTFORWARD, seed=1)
    start_until(runner, probe, Stage.REACH)
    runner.stage_fault(StagedFault.TRACKER_LOST)  # the dashboard's button
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    first = ended(view, 1)
    state = runner.rehearsal.control("state")
    scene = runner.lab.scene
    assert first.outcome.value == "aborted" and first.reason.startswith("tracker_lost")
    assert state["speed"] < 1e-3  # the arm holds where it stopped, short of H
    assert np.linalg.norm(np.asarray(state["pose"][:3]) - scene.point("handover_point")) > 0.02
    # Keep the marker hidden until the repeated trial has said it waits for it (the staged 1.5 s
    # loss may or may not be over by the time the trial checks, depending on the machine's load).
    runner.rehearsal.publisher.occlude(CEILING_S)
    probe.wait(lambda v: v.step is not None and v.step.value == "ready", what="ready to repeat",
               timeout=READY_CEILING_S)
    runner.start_trial()
    waiting = probe.wait(lambda v: v.state.running_trial == 2 and v.ready_wait is not None,
                         what="the repeat (trial 2) waiting for the hand")
    assert "no valid hand sample" in waiting.ready_wait and waiting.stage == Stage.LOADED
    runner.rehearsal.publisher.occlude(0.0)  # the tracker sees the hand again
    view = probe.wait(lambda v: ended(v, 2) is not None, what="trial 2 ended")
    second = ended(view, 2)
    assert (second.interaction, second.attempt, second.outcome.value) == (1, 2, "completed"), \
        second.reason


def test_a_protective_stop_during_hold_aborts_and_the_trial_completes_after_recovery(rehearsed):
    """Slow (about 25 s): two trials on the wall clock, and Recover waits out the controller's 5 s
    rule before the protective stop may be unlocked, as a UR's does."""
    runner, probe = rehearsed
    runner.open("F02", Scenario.STRAIGHTFORWARD, seed=2)
    start_until(runner, probe, Stage.HOLD)
    runner.stage_fault(StagedFault.PROTECTIVE_STOP)
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    assert ended(view, 1).outcome.value == "aborted" and "protective stop" in ended(view, 1).reason
    assert "protective stop" in view.arm_fault
    with pytest.raises(RefusedAction, match=r"Start refused: the arm has a fault \(protective stop"):
        runner.start_trial()  # no trial on an arm in a protective stop
    runner.recover_arm(inspected=True)  # waits out the controller's 5 s rule
    probe.wait(lambda v: v.step is not None and v.step.value == "ready", what="ready again",
               timeout=READY_CEILING_S)
    runner.start_trial()
    view = probe.wait(lambda v: any(t.outcome and t.outcome.value == "completed"
                                    for t in v.trials), what="a completed trial")
    assert next(t for t in view.trials if t.outcome.value == "completed").interaction == 1


def test_an_rtde_drop_mid_reach_costs_that_trial_only_and_the_next_one_releases_the_object(
        rehearsed):
    """Every RTDE socket of the stand-in dropped mid-reach (the arm's and the tool-output gripper's,
    as a bumped cable or a switch reboot drops them): the trial ends, Recover connects both again,
    and the next trial opens the gripper on the pull. Before, the gripper's link stayed dead: the
    next trial held the object out and its release ended the rig ("write: Broken pipe")."""
    runner, probe = rehearsed
    runner.open("F06", Scenario.STRAIGHTFORWARD, seed=6)
    start_until(runner, probe, Stage.REACH)
    assert runner.rehearsal.control("drop_sockets")["ok"]
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    assert ended(view, 1).outcome.value == "aborted" and view.arm_fault, ended(view, 1).reason
    runner.recover_arm(inspected=True)
    assert "gripper's RTDE IO link connected again" in " ".join(runner.view.messages)
    probe.wait(lambda v: v.step is not None and v.step.value == "ready", what="ready again",
               timeout=READY_CEILING_S)
    runner.start_trial()
    view = probe.wait(lambda v: ended(v, 2) is not None, what="trial 2 ended")
    second = ended(view, 2)
    assert (second.interaction, second.outcome.value) == (1, "completed"), second.reason
    assert runner.rig.alive  # completed: the gripper opened on the pull, through its new link


def test_a_controller_that_stalls_mid_reach_ends_the_trial_and_the_rig_lives_through_the_stop(
        rehearsed):
    """The stand-in sends nothing for 3 s: the rig sees the silence, ends the trial and stops the arm,
    each stop command waiting its own 1 s for an answer that does not come. Those waits are the stop
    path, not a hung rig: the backstop must not kill it (it did, 0.5 s into the stop, under load)."""
    runner, probe = rehearsed
    runner.open("F05", Scenario.STRAIGHTFORWARD, seed=5)
    start_until(runner, probe, Stage.REACH)
    rig = runner.rig.pid
    runner.rehearsal.control("stall", seconds=3.0)
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    first = ended(view, 1)
    assert first.outcome.value == "aborted" and "no new state" in first.reason, first.reason
    assert "rig process ended" not in (view.arm_fault or ""), view.arm_fault
    assert runner.rig.alive and runner.rig.pid == rig


def test_no_pull_ends_the_trial_not_taken_and_it_is_repeated_not_rated(rehearsed):
    """Slow (30-60 s): the hold waits out the product's release timeout (10 s) on the wall clock, and
    a second whole trial follows; the timeout is the product's default on purpose (``rehearsed``)."""
    runner, probe = rehearsed
    runner.refuse_object(True)  # this participant never takes the object
    runner.open("F03", Scenario.STRAIGHTFORWARD, seed=3)
    start_until(runner, probe, Stage.HOLD)  # nothing pulls: the hold ends at the release timeout
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    first = ended(view, 1)
    assert first.outcome.value == "not_taken" and first.release_s is None, first.reason
    assert first.hold_s is not None and first.retract_end_s is not None
    assert view.step.value == "ready"  # repeated, never rated
    runner.refuse_object(False)
    runner.start_trial()
    view = probe.wait(lambda v: ended(v, 2) is not None, what="trial 2 ended")
    assert (ended(view, 2).interaction, ended(view, 2).outcome.value) == (1, "completed"), \
        ended(view, 2).reason


def test_the_rig_process_killed_mid_reach_stops_the_arm_and_the_next_trial_completes(rehearsed):
    """Slow (about 30 s): two trials on the wall clock on the rehearsal rig, and a fresh rig process
    started and connected to the stand-in UR between them."""
    runner, probe = rehearsed
    runner.open("F04", Scenario.STRAIGHTFORWARD, seed=4)
    start_until(runner, probe, Stage.REACH)
    killed = runner.rig.pid
    # Kill the rig while the arm moves (the stop must be seen by the stand-in controller), not at a
    # moment guessed on the clock: once the stand-in reports the TCP moving during the reach.
    wait_for(lambda: moving(runner), "the stand-in to report the arm moving in the reach",
             seen=lambda: (runner.view.stage, runner.rehearsal.control("state")))
    runner.stage_fault(StagedFault.RIG_KILLED)
    view = probe.wait(lambda v: ended(v, 1) is not None, what="trial 1 ended")
    assert "killed by signal 9" in view.arm_fault and "during reach" in view.arm_fault
    assert ended(view, 1).outcome.value == "aborted"
    state = wait_for(lambda: stopped(runner.rehearsal.control("state")),
                     "the stand-in to see its program end and the arm stand still",
                     seen=lambda: runner.rehearsal.control("state"))
    assert any("ended" in event for event in state["events"])
    runner.start_trial()  # a fresh rig process
    view = probe.wait(lambda v: ended(v, 2) is not None, what="trial 2 ended")
    assert runner.rig.pid != killed
    assert ended(view, 2).outcome.value == "completed", ended(view, 2).reason


def test_a_resume_on_a_different_arm_is_refused_until_the_experimenter_confirms(rehearsed):
    runner, _ = rehearsed
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    mock = SessionRunner(runner.study, lab, realtime=False)
    mock.open("F05", Scenario.PERTURBED, seed=5)
    mock.close()
    path = runner.study / "F05.sqlite"
    with sqlite3.connect(path) as db:
        before = db.execute("SELECT count(*) FROM events").fetchone()[0]
    with pytest.raises(RefusedAction, match=r"different rig \(arm.kind 'mock' → 'ur'"):
        runner.open("F05")
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT count(*) FROM events").fetchone()[0] == before  # nothing written
    runner.open("F05", confirm_rig_change=True)
    with sqlite3.connect(path) as db:
        kinds = [row[0] for row in db.execute("SELECT kind FROM events WHERE seq > ?", [before])]
        devices = json.loads(db.execute("SELECT payload FROM events WHERE kind = 'devices_recorded' "
                                        "ORDER BY seq DESC").fetchone()[0])["devices"]
    assert kinds[:3] == ["session_resumed", "rig_change_confirmed", "devices_recorded"]
    assert devices["arm"] == "ur" and devices["polyscope_version"].startswith("3.15")


@pytest.mark.parametrize(("hand", "shown"), [
    ("udp", "UDP on 127.0.0.1:"),
    # the rigid body "hand" of a stand-in Motive (NatNet 3.1, unicast, beside a second rigid body),
    # read by the real natnet client in the rig process
    ("natnet", "NatNet rigid body 'hand' (id 1) from Motive (NatNet 3.1"),
])
def test_the_rehearsal_plays_the_hand_over_udp_and_natnet_too(tmp_path, hand, shown):
    """Slow (about 10 s each alone): a rehearsal of its own (stand-in UR, the hand over UDP or a stand-in
    Motive) and a whole trial on the wall clock."""
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    rehearsal = Rehearsal(lab, hand=hand)
    runner = SessionRunner(tmp_path / "study", lab, rehearsal=rehearsal, realtime_priority=True)
    runner.set_auto(True)
    probe = Probe(runner)
    try:
        runner.open("U01", Scenario.STRAIGHTFORWARD, seed=6)
        assert runner.view.hand.startswith(shown), runner.view.hand
        trial = run_trial(runner, probe)  # repeated if the machine starved it
    finally:
        runner.close()
    assert trial.outcome.value == "completed" and trial.peak_pull_n >= 10.0, trial.reason


def test_a_rehearsed_session_resumes_in_a_new_rehearsal_without_a_rig_change(tmp_path):
    """A new rehearsal has its own loopback address and stream name: not a different rig."""
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    hosts = []
    for attempt in range(2):
        runner = SessionRunner(tmp_path / "study", lab, rehearsal=Rehearsal(lab))
        try:
            hosts.append(runner.lab.ur.host)
            runner.open("F06", Scenario.PERTURBED if attempt == 0 else None, seed=6)
        finally:
            runner.close()
    with sqlite3.connect(tmp_path / "study" / "F06.sqlite") as db:
        kinds = [row[0] for row in db.execute("SELECT kind FROM events ORDER BY seq")]
        rigs = [json.loads(row[0])["rig"] for row in db.execute(
            "SELECT payload FROM events WHERE kind = 'devices_recorded' ORDER BY seq")]
    assert hosts[0] != hosts[1]
    assert "rig_change_confirmed" not in kinds and kinds.count("devices_recorded") == 2
    assert rigs[0] == rigs[1] and rigs[0]["ur"]["host"] == "rehearsal"
    assert rigs[0]["arm"]["kind"] == "ur"
