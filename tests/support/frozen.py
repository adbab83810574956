"""An application frozen in the middle of a reach: ``handover run-session`` drives a stand-in UR, and
is stopped with SIGSTOP (as Ctrl-Z in its terminal stops it) once the reach is under way. What the
controller received afterwards says whether anything stopped the arm (issue 25, item 1)."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from support.engine import BRIEF_PROTOCOL, protocol_toml
from support.processes import descendants, still_alive
from support.ur import Standin, servo_targets, servo_targets_once_stopped
from support.waiting import CEILING_S, tail, wait_for

#: Servo targets at the controller before the freeze: the first reach is under way (0.2 s at 125 Hz).
UNDER_WAY = 25


@dataclass
class Frozen:
    """What the controller received around the freeze of the application."""

    targets_after: int  # servo targets the controller received after the SIGSTOP
    last_servo_s: float  # from the SIGSTOP to the last servo target [s]


def lab_toml(host: str) -> str:
    """A UR at ``host`` (the stand-in), the simulated hand in the rig, the briefest protocol; the
    controller's watchdog patient (100 s), so that only the rig can end the stream."""
    return (f'[arm]\nkind = "ur"\n[ur]\nhost = "{host}"\nwatchdog_hz = 0.01\n'
            f"[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}")


def start_session(folder: Path, ur: Standin) -> subprocess.Popen:
    """``run-session --auto`` on the stand-in, its stderr in ``folder/run.log``."""
    lab = folder / "lab.toml"
    lab.write_text(lab_toml(ur.host))
    with (folder / "run.log").open("w") as err:
        return subprocess.Popen(
            [sys.executable, "-m", "app.cli", "run-session", "--study", str(folder / "study"),
             "--participant", "F1", "--scenario", "perturbed", "--auto", "--no-progress",
             "--config", str(lab)],
            stdout=subprocess.DEVNULL, stderr=err, process_group=0)  # a job of its own, as in a terminal


def reach_under_way(run: subprocess.Popen, ur: Standin, folder: Path) -> float:
    """Wait until the controller has :data:`UNDER_WAY` servo targets; the moment [monotonic s]."""
    wait_for(lambda: len(servo_targets(ur.control)) >= UNDER_WAY or run.poll() is not None,
             f"{UNDER_WAY} servo targets at the stand-in (the first reach under way)",
             timeout=CEILING_S * 3,
             seen=lambda: f"exit code {run.poll()}; {tail((folder / 'run.log').read_text())}")
    assert run.poll() is None, tail((folder / "run.log").read_text())
    return time.monotonic()


def freeze_mid_reach(run: subprocess.Popen, ur: Standin, folder: Path, ctrl_z: bool = False) -> Frozen:
    """Freeze ``run`` once its reach is under way: SIGSTOP to its own pid, or (``ctrl_z``) SIGTSTP to
    its process group, as Ctrl-Z in its terminal does. Wait until the controller's script has
    stopped (the stream ended, by whatever ended it); the application stays frozen."""
    reach_under_way(run, ur, folder)
    if ctrl_z:
        os.killpg(run.pid, signal.SIGTSTP)
    else:
        os.kill(run.pid, signal.SIGSTOP)
    frozen_at = time.monotonic()
    before = len(servo_targets(ur.control))
    received = servo_targets_once_stopped(ur.control)
    return Frozen(targets_after=len(received) - before, last_servo_s=received[-1][0] - frozen_at)


def thaw(run: subprocess.Popen) -> None:
    """Let the frozen application (and whatever Ctrl-Z stopped with it) run again."""
    os.killpg(run.pid, signal.SIGCONT)


def stored_trial(database: Path, trial_index: int) -> tuple[str, str | None] | None:
    """The outcome and reason of a stored trial (None before it is stored); read-only."""
    try:
        with sqlite3.connect(f"file:{database}?mode=ro", uri=True) as conn:
            return conn.execute("SELECT outcome, reason FROM trials WHERE trial_index = ? AND "
                                "outcome IS NOT NULL", (trial_index,)).fetchone()
    except sqlite3.Error:
        return None


def end(run: subprocess.Popen) -> None:
    """Kill the session (its own pid, thawed first) and wait for its rig and learner to end."""
    children = descendants(run.pid)
    if run.poll() is None:
        thaw(run)
        run.kill()
    run.wait()
    assert not still_alive(children, CEILING_S), "the session's processes outlived it"
