"""The rig's real-time priority by default, said at start where the OS refuses it, and the dashboard's
warning as soon as a trial's timing runs late (``[loop] realtime_priority``, robot_io.rig.timing)."""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pydantic import ValidationError
from support.engine import SHORT_PROTOCOL
from support.priority import without_priority
from support.runner import Probe
from support.waiting import tail, wait_for

from app.cli import main
from app.session.cli import add_rig_arguments, open_runner
from app.session.config import LabConfig, load_lab_config
from app.session.runner import RunnerView, SessionRunner
from app.ui.status_text import devices_markdown
from robot_io.clock import priority_refusal
from robot_io.hands.simulated_hand import Scenario

LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": SHORT_PROTOCOL})
#: How long the test holds the rig off the CPU in the middle of a reach, as a busy machine does [s].
HELD_S = 0.06


def rig_arguments(study: Path, *flags: str) -> argparse.Namespace:
    """The command line ``serve`` and ``run-session`` share, as the user typed it."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--study", type=Path)
    add_rig_arguments(parser)
    return parser.parse_args(["--study", str(study), *flags])


def thread_policies(pid: int) -> dict[int, int]:
    """The scheduling policy of each thread of process ``pid``."""
    return {int(tid): os.sched_getscheduler(int(tid)) for tid in os.listdir(f"/proc/{pid}/task")}


@pytest.mark.parametrize(("flags", "policy", "words"), [
    ([], os.SCHED_FIFO, "real-time priority (SCHED_FIFO)"),
    (["--no-realtime-priority"], os.SCHED_OTHER, "no real-time priority"),
], ids=["default", "no-realtime-priority"])
def test_a_rig_runs_real_time_by_default_where_the_os_permits_it(tmp_path, flags, policy, words):
    """With no flag and no setting, every thread of the rig process runs under SCHED_FIFO, and the
    dashboard says so by the devices; ``--no-realtime-priority`` keeps it on the normal policy."""
    if (refusal := priority_refusal()) is not None:
        pytest.skip(f"this machine does not permit SCHED_FIFO ({refusal})")
    with open_runner(rig_arguments(tmp_path / "study", *flags), LAB, realtime=True) as runner:
        runner.open("P01", Scenario.PERTURBED)
        policies = thread_policies(runner.rig.pid)
        assert policies and set(policies.values()) == {policy}, policies
        assert f"- **timing**: {words}" in devices_markdown(runner.view)


def serve_without_priority(tmp_path: Path, *flags: str) -> subprocess.Popen:
    """``handover serve`` in a process that may not have SCHED_FIFO; its output in tmp_path/serve.log."""
    log = (tmp_path / "serve.log").open("w")
    return subprocess.Popen([*without_priority(), sys.executable, "-m", "app.cli", "serve",
                             "--study", str(tmp_path / "study"), "--tablet-port", "0",
                             "--dashboard-port", "0", *flags],
                            stdout=log, stderr=subprocess.STDOUT, text=True)


def test_without_permission_the_rig_says_so_at_start_or_refuses_when_required(tmp_path):
    """Where the OS refuses SCHED_FIFO, ``serve`` says so at start, with the OS's reason and how to
    grant it, and serves on the normal policy; with ``--realtime-priority`` it refuses to start."""
    log = tmp_path / "serve.log"
    server = serve_without_priority(tmp_path)
    try:
        out = wait_for(lambda: "dashboard token:" in (text := log.read_text()) and text,
                       "serve to start", seen=lambda: tail(log.read_text()))
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(60)
    assert "the rig runs without real-time priority (the OS refused SCHED_FIFO: Operation not " \
           "permitted)" in out, out
    assert "setcap cap_sys_nice+ep" in out and "rtprio" in out and "docs/hardware.md" in out
    refused = serve_without_priority(tmp_path, "--realtime-priority")
    assert refused.wait(120) == 2, log.read_text()
    assert "[loop] realtime_priority = true (or --realtime-priority), but the OS refused " \
           "SCHED_FIFO" in log.read_text(), log.read_text()


def late_trial(view: RunnerView) -> int:
    """The trial the view's timing warning is about."""
    assert view.timing_warning is not None
    return int(re.match(r"timing degraded in trial (\d+)", view.timing_warning)[1])


def ended(view: RunnerView) -> bool:
    """Whether the trial of the view's timing warning is stored with its outcome."""
    return any(t.trial_index == late_trial(view) and t.outcome is not None for t in view.trials)


def test_a_rig_held_off_the_cpu_mid_reach_is_reported_on_the_dashboard(tmp_path, caplog):
    """The rig process is held off the CPU for HELD_S in the middle of a reach (SIGSTOP, SIGCONT:
    what a busy machine does to a process without real-time priority); the dashboard's devices say
    by how much the control cycles ran late, and that the rig runs without real-time priority. The
    terminal's last word on the trial is the dashboard's (before, the terminal kept the trial's
    first report and the dashboard its latest: issue 45, item 16)."""
    runner = SessionRunner(tmp_path / "study", LAB, auto_experimenter=True)
    probe = Probe(runner)
    try:
        runner.set_auto(True)
        runner.open("P01", Scenario.PERTURBED)
        rig = runner.rig
        wait_for(lambda: rig.stream.count > 10 and not rig.stream.finished, "a trial's reach",
                 seen=lambda: (rig.stream.count, rig.stream.finished))
        os.kill(rig.pid, signal.SIGSTOP)
        time.sleep(HELD_S)  # holds the rig off the CPU at least this long; nothing is measured here
        os.kill(rig.pid, signal.SIGCONT)
        view = probe.wait(lambda v: v.timing_warning is not None and ended(v),
                          what="the late trial stored, its timing shown")
    finally:
        runner.close()
    said = [r.getMessage() for r in caplog.records
            if r.getMessage().startswith(f"timing degraded in trial {late_trial(view)}")]
    assert said[-1] == view.timing_warning and " so far" not in said[-1], said
    late = re.search(r"(\d+) control cycles? started late, by up to (\d+) ms", view.timing_warning)
    assert late and int(late[1]) >= 1 and int(late[2]) >= HELD_S * 1e3 - 8, view.timing_warning
    assert "the rig runs without real-time priority: grant it" in view.timing_warning
    devices = devices_markdown(view)
    assert ("- **timing**: no real-time priority (normal scheduling): trials may run late on a busy "
            f"machine — ⚠ **{view.timing_warning}**") in devices, devices
    assert any("the rig's timing runs late (see Devices)" in m for m in view.messages), view.messages


@pytest.mark.parametrize(("text", "setting"), [("", "auto"), ('realtime_priority = "auto"', "auto"),
                                               ("realtime_priority = true", True),
                                               ("realtime_priority = false", False)])
def test_lab_files_say_auto_true_or_false(tmp_path, text, setting):
    """A lab.toml of before (true or false) still loads; without the key the rig asks for priority
    where permitted."""
    (tmp_path / "lab.toml").write_text(f"[loop]\n{text}\n")
    assert load_lab_config(tmp_path / "lab.toml").loop.realtime_priority == setting


@pytest.mark.parametrize("value", ['"always"', '"yes"', '"true"', "1", '"on"'])
def test_an_unknown_priority_setting_is_refused_naming_the_values(tmp_path, capsys, value):
    """``realtime_priority = "yes"`` was read as true, 1 and "on" too (pydantic's lax booleans;
    issue 45, item 10): only true, false and "auto" are settings, and the refusal names them."""
    (tmp_path / "lab.toml").write_text(f'[loop]\nrealtime_priority = {value}\n')
    with pytest.raises(ValidationError, match=r"loop\.realtime_priority"):
        load_lab_config(tmp_path / "lab.toml")
    assert main(["run-session", "--study", str(tmp_path / "study"), "--participant", "P01",
                 "--scenario", "perturbed", "--auto", "--config", str(tmp_path / "lab.toml")]) == 2
    read = value.strip('"') if value.startswith('"') else int(value)  # as TOML reads it
    assert (f'loop.realtime_priority = {read!r}: must be true, false or "auto" (without quotes: '
            'true, false; with: "auto")') in capsys.readouterr().err
