"""``run-session`` ended by a signal mid-trial, as a lab's process manager (SIGTERM) or the
experimenter's Ctrl-C (SIGINT) ends it: the arm is stopped, the running trial is recorded aborted with
the reason, the session resumes, and neither the command nor its rig prints a traceback. Ctrl-C in
a terminal signals the whole foreground process group, the rig and the learner worker too, not
only the command."""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import subprocess
import sys

import pytest
from support.browser import NEVER_TAKES
from support.engine import SESSION_LOOP_TOML, SHORT_PROTOCOL, protocol_toml
from support.processes import (
    command_line,
    descendants,
    has_signal,
    signal_masks,
    still_alive,
)
from support.waiting import CEILING_S, tail, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.soak]


def read_only(path) -> contextlib.closing[sqlite3.Connection]:
    return contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True))


def stages_of_trial_1(path) -> list[str]:
    try:
        with read_only(path) as conn:
            return [row[0] for row in conn.execute(
                "SELECT json_extract(payload, '$.stage') FROM events WHERE kind = 'trial_stage'")]
    except sqlite3.Error:
        return []


@pytest.mark.parametrize(("signum", "group", "rehearse"), [
    pytest.param(signal.SIGTERM, False, False, id="SIGTERM"),
    pytest.param(signal.SIGINT, False, False, id="SIGINT"),
    pytest.param(signal.SIGINT, True, False, id="Ctrl-C (SIGINT to the process group)"),
    # the stand-in controller, too, is started by the command: as a real controller, Ctrl-C
    # must not reach it (it took the arm away mid-trial)
    pytest.param(signal.SIGINT, True, True, id="Ctrl-C, rehearsed", marks=pytest.mark.standin)])
def test_a_signal_mid_trial_closes_the_session_like_ctrl_c(tmp_path, signum, group, rehearse):
    """Slow (20-30 s in a loaded full run): a ``run-session`` process whose first θ waits for its
    learner (the forkserver imports torch), then trial 1 on the wall clock up to its hold, the
    signal and the close."""
    study, log, lab = tmp_path / "study", tmp_path / "run.log", tmp_path / "lab.toml"
    # the simulated participant never takes the object: trial 1 holds it out until it is ended
    lab.write_text(f"{SESSION_LOOP_TOML}\n[protocol]\n{protocol_toml(SHORT_PROTOCOL)}\n{NEVER_TAKES}")
    with log.open("w") as out:
        run = subprocess.Popen([sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
                                "--participant", "T01", "--scenario", "perturbed", "--auto",
                                "--rehearse" if rehearse else "--realtime", "--no-progress",
                                "--config", str(lab)],
                               stdout=out, stderr=subprocess.STDOUT, start_new_session=group)
    try:
        wait_for(lambda: "hold" in stages_of_trial_1(study / "T01.sqlite"),
                 "trial 1 to hold the object out", timeout=3 * CEILING_S,
                 seen=lambda: f"stages {stages_of_trial_1(study / 'T01.sqlite')}; "
                              f"log {tail(log.read_text())}")
        if group:  # as a terminal's Ctrl-C: the command and every process it started
            os.killpg(run.pid, signum)
        else:
            run.send_signal(signum)  # the writing process itself, by its own PID
        code = run.wait(CEILING_S)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    output = log.read_text()
    with read_only(study / "T01.sqlite") as conn:
        [(outcome, reason)] = conn.execute(
            "SELECT outcome, reason FROM trials WHERE trial_index = 1").fetchall()
    assert outcome == "aborted" and signal.Signals(signum).name in reason, (outcome, reason, output)
    assert "Traceback" not in output, tail(output)
    assert code == 128 + signum and "--resume continues it" in output, (code, tail(output))


#: How the children that run-session starts through multiprocessing (rig, hand publisher, learner
#: forkserver) begin; not the resource tracker, nor the stand-in controller (a session of its own).
STARTED_BY_MULTIPROCESSING = ("spawn_main(", "forkserver import main")


def starting_children(pid: int) -> list[int]:
    """The children that ``pid`` started through multiprocessing which have not yet ignored SIGINT:
    Python's own handler (KeyboardInterrupt) is set, so they are still starting (imports,
    unpickling the arguments)."""
    return [child for child in descendants(pid)
            if any(start in command_line(child) for start in STARTED_BY_MULTIPROCESSING)
            and has_signal(signal_masks(child).get("SigCgt", 0), signal.SIGINT)]


@pytest.mark.parametrize("rehearse", [
    pytest.param(False, id="real-time"),
    pytest.param(True, id="rehearsed", marks=pytest.mark.standin)])
def test_a_ctrl_c_while_a_child_still_starts_prints_no_traceback(tmp_path, rehearse):
    """Ctrl-C in a session's first seconds, while the rig (or the hand publisher) is still
    importing: before robot_io.child_signals, the child died of a KeyboardInterrupt and printed
    its traceback (6 of 6 tries); now the SIGINT waits until the child ignores it."""
    study = tmp_path / "study"
    run = subprocess.Popen([sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
                            "--participant", "T01", "--scenario", "perturbed", "--auto",
                            "--rehearse" if rehearse else "--realtime", "--no-progress"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           start_new_session=True)
    try:
        starting = wait_for(lambda: starting_children(run.pid), "a child of run-session to start",
                            poll=0.002, seen=lambda: {p: signal_masks(p) for p in descendants(run.pid)})
        group = descendants(run.pid)
        os.killpg(run.pid, signal.SIGINT)  # as a terminal's Ctrl-C
        output, _ = run.communicate(timeout=CEILING_S)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert "Traceback" not in output, (starting, tail(output))
    assert run.returncode == 128 + signal.SIGINT and "--resume continues it" in output, \
        (run.returncode, tail(output))
    assert still_alive(group, CEILING_S) == []
