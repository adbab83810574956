"""Issue 45, item 5, on the commands: ``run-session`` with a study plan (``[study]`` in --config)
needs no --scenario — it takes the plan's proposal and says so — and a --scenario other than the
proposal runs, recorded and reported as a deviation (``handover report``'s design line and Data
problems). Two participants created at once get two of the plan's places, never one twice: the
proposal is read and the session created in one step for the study folder.

Each session is the briefest protocol (3 handovers, headless, simulated time); the module takes
about 60 s, most of it the learner's start in each run-session."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from support.engine import BRIEF_PROTOCOL, SESSION_LOOP_TOML, protocol_toml
from support.waiting import tail

from app.analysis.report import build_report
from app.cli import main
from app.protocol.design import StudyPlan, recorded_assignment
from session_store.catalog import stored_configs

PLAN = StudyPlan(design="between", group_size=2, seed=5)


def lab_file(folder: Path) -> Path:
    lab = folder / "lab.toml"
    lab.write_text(f"{SESSION_LOOP_TOML}[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}\n[study]\n"
                   f'design = "between"\ngroup_size = 2\nseed = 5\n')
    return lab


def test_run_session_takes_the_plans_proposal_and_a_deviation_is_reported(tmp_path, capsys):
    """Slow (~30 s in a loaded full run): two whole simulated sessions through `run-session --auto`
    (each with its learner process) and two reports of the study, as the lab runs them."""
    lab, study = lab_file(tmp_path), tmp_path / "study"
    first, second = PLAN.proposal(1).proposed, PLAN.proposal(2).proposed
    assert main(["run-session", "--study", str(study), "--participant", "R01", "--auto",
                 "--config", str(lab), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert f"R01 ({first.value}, seed " in out
    assert f"; study plan: participant 1 of 4: {first.value}): " in out
    other = next(s for s in PLAN.scenarios if s is not second)
    assert main(["run-session", "--study", str(study), "--participant", "R02", "--auto",
                 "--config", str(lab), "--no-progress", "--scenario", other.value]) == 0
    assert (f"study plan: participant 2 of 4: {second.value} — DEVIATION: ran {other.value}"
            in capsys.readouterr().out)
    report = build_report(study, tmp_path / "report")
    assert "1 deviation from the plan (under Data problems)" in report.design.line
    assert report.design.deviations == [
        f"R02: {other.value}, the plan proposed {second.value} (participant 2 of 4: "
        f"{second.value})"]
    assert main(["report", str(study), "--out", str(tmp_path / "cli")]) == 0
    terminal = capsys.readouterr()
    assert terminal.out.startswith(report.design.line)
    assert f"warning: study plan: {report.design.deviations[0]}" in terminal.err


@pytest.mark.slow
def test_two_participants_created_at_once_get_two_places_of_the_plan(tmp_path):
    """Slow (~25 s in a loaded full run): two whole `run-session --auto` processes at once, each
    importing the application and starting its learner, so that they create their participants at
    the same moment."""
    lab, study = lab_file(tmp_path), tmp_path / "study"
    logs = {code: tmp_path / f"{code}.log" for code in ("C01", "C02")}
    runs = {}
    for code, log in logs.items():
        with log.open("w") as err:
            runs[code] = subprocess.Popen(
                [sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
                 "--participant", code, "--auto", "--no-progress", "--config", str(lab)],
                stdout=subprocess.DEVNULL, stderr=err)
    try:
        for code, run in runs.items():  # a ceiling for a hung session, not a measurement
            assert run.wait(timeout=600) == 0, tail(logs[code].read_text())
    finally:
        for run in runs.values():
            if run.poll() is None:
                run.kill()
    configs = stored_configs(study)
    places = {code: recorded_assignment(configs[code]) for code in logs}
    assert sorted(a.position for a in places.values()) == [1, 2]
    assert {configs[code]["scenario"] for code in logs} == {a.proposed.value
                                                           for a in places.values()}
