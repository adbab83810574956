"""Two writers on one participant, as a careless lab would start them: the second — another
``run-session --resume`` or ``serve`` with the participant — is refused with the holder named and
writes nothing; the first finishes its 34 interactions, none completed twice. And the other way
round: ``serve`` holding a participant refuses ``run-session``. (How fast the refusal comes is
measured by benchmarks/writer_refusal.py.)"""

from __future__ import annotations

import signal
import sqlite3
import subprocess
import sys
import time

import pytest
from support.browser import free_port
from support.store import event_count

from app.cli import main

HANDOVER = [sys.executable, "-m", "app.cli"]


def _serve(study, *extra: str) -> list[str]:
    return [*HANDOVER, "serve", "--study", str(study), "--tablet-port", str(free_port()),
            "--dashboard-port", str(free_port()), "--token", "t", *extra]


@pytest.mark.slow
def test_a_second_writer_is_refused_and_the_first_finishes_34_interactions(tmp_path, capsys):
    study, database = tmp_path / "study", tmp_path / "study" / "P09.sqlite"
    first = subprocess.Popen([*HANDOVER, "run-session", "--study", str(study), "--participant",
                              "P09", "--scenario", "perturbed", "--auto", "--seed", "7",
                              "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    while event_count(database) < 3:
        assert first.poll() is None, first.stderr.read()
        time.sleep(0.05)
    for second in ([*HANDOVER, "run-session", "--study", str(study), "--participant", "P09",
                    "--auto", "--resume", "--no-progress"],
                   _serve(study, "--participant", "P09")):
        refused = subprocess.run(second, capture_output=True, text=True, timeout=120)
        assert refused.returncode == 2, refused.stderr
        assert f"participant 'P09' is open for writing by pid {first.pid} on " in refused.stderr
        assert "run-session --study" in refused.stderr and "refused before writing" in refused.stderr
        assert "Traceback" not in refused.stderr
    _, err = first.communicate(timeout=900)
    assert first.returncode == 0, err[-2000:]
    with sqlite3.connect(database) as conn:
        completed = conn.execute("SELECT interaction FROM trials WHERE outcome = 'completed'"
                                 ).fetchall()
        resumed = conn.execute("SELECT count(*) FROM events WHERE kind = 'session_resumed'"
                               ).fetchone()[0]
    assert len(completed) == len(set(completed)) == 34
    assert resumed == 0  # the refused writers wrote nothing
    assert main(["doctor", str(study)]) == 0
    assert "P09.sqlite: OK" in capsys.readouterr().out


@pytest.mark.slow
def test_serve_holding_a_participant_refuses_run_session(tmp_path):
    study = tmp_path / "study"
    log = tmp_path / "serve.log"
    with log.open("w") as out:
        serve = subprocess.Popen(_serve(study, "--participant", "P10", "--scenario", "perturbed",
                                        "--seed", "8"), stdout=out, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 120
        while "dashboard token" not in log.read_text():
            assert serve.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        events = event_count(study / "P10.sqlite")
        refused = subprocess.run([*HANDOVER, "run-session", "--study", str(study), "--participant",
                                  "P10", "--auto", "--resume", "--no-progress"],
                                 capture_output=True, text=True, timeout=120)
        assert refused.returncode == 2
        assert f"open for writing by pid {serve.pid} on " in refused.stderr
        assert "serve --study" in refused.stderr
        assert event_count(study / "P10.sqlite") == events
    finally:
        serve.send_signal(signal.SIGINT)
        serve.wait(60)
    assert serve.returncode == 0, log.read_text()
