"""Two writers on one participant, as a careless lab would start them: the second — another
``run-session --resume`` or ``serve`` with the participant — is refused with the holder named and
writes nothing; the first finishes its session (every phase of the short protocol), none completed
twice. And the other way round: ``serve`` holding a participant refuses ``run-session``. (How fast
the refusal comes is measured by benchmarks/writer_refusal.py. The paper's 34 interactions run end
to end through ``run-session`` in tests/protocol/test_resume_exact.py, uninterrupted and killed.)"""

from __future__ import annotations

import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from support.engine import SESSION_LOOP_TOML, SHORT_PROTOCOL, protocol_toml
from support.processes import stopped, thread_states
from support.store import event_count, events
from support.waiting import CEILING_S, tail, wait_for

from app.cli import main

HANDOVER = [sys.executable, "-m", "app.cli"]


def _serve(study, *extra: str) -> list[str]:
    return [*HANDOVER, "serve", "--study", str(study), "--tablet-port", "0",
            "--dashboard-port", "0", "--token", "t", *extra]


def running(process: subprocess.Popen, log: Path) -> bool:
    """True while ``process`` runs; its end is an error naming its exit code and its log's tail
    (a dead writer is not a slow one: the wait ends at once)."""
    if (code := process.poll()) is not None:
        raise AssertionError(f"pid {process.pid} ended (exit code {code}) before the awaited "
                             f"state; its log: {tail(log.read_text())}")
    return True


@pytest.mark.slow
@pytest.mark.soak
def test_a_second_writer_is_refused_and_the_first_finishes_its_session(tmp_path, capsys):
    """Slow (~25 s in a full run): three `handover` processes, a whole `run-session` of the short
    protocol and the two refused second writers (`run-session --resume` and `serve`), each paying
    the application's start-up."""
    study, database = tmp_path / "study", tmp_path / "study" / "P09.sqlite"
    log, lab = tmp_path / "first.log", tmp_path / "lab.toml"
    lab.write_text(f"{SESSION_LOOP_TOML}\n[protocol]\n{protocol_toml(SHORT_PROTOCOL)}")
    with log.open("w") as out:  # a file, not a pipe nobody reads while the session runs
        first = subprocess.Popen([*HANDOVER, "run-session", "--study", str(study), "--participant",
                                  "P09", "--scenario", "perturbed", "--auto", "--seed", "7",
                                  "--no-progress", "--config", str(lab)],
                                 stdout=out, stderr=subprocess.STDOUT, text=True)
    try:
        wait_for(lambda: running(first, log) and event_count(database) >= 3,
                 "the first writer to have stored 3 events", seen=lambda: event_count(database))
        # The first writer is held mid-session while the second ones try, whatever the machine's
        # load: a short session could otherwise end before a slow second writer had started.
        first.send_signal(signal.SIGSTOP)
        wait_for(lambda: stopped(first.pid), "every thread of the first writer stopped by SIGSTOP",
                 seen=lambda: thread_states(first.pid))
        for second in ([*HANDOVER, "run-session", "--study", str(study), "--participant", "P09",
                        "--auto", "--resume", "--no-progress"],
                       _serve(study, "--participant", "P09")):
            refused = subprocess.run(second, capture_output=True, text=True, timeout=120)
            assert refused.returncode == 2, (refused.stderr, f"the first writer: exit code "
                                             f"{first.poll()} (None: running)")
            assert f"participant 'P09' is open for writing by pid {first.pid} on " in refused.stderr
            assert "run-session --study" in refused.stderr
            assert "refused before writing" in refused.stderr
            assert "Traceback" not in refused.stderr
        first.send_signal(signal.SIGCONT)
        # A ceiling for a hung session (it takes about half a minute idle), not a measurement.
        assert first.wait(timeout=900) == 0, tail(log.read_text())
    finally:
        if first.poll() is None:  # the test failed: end the writer it started, by its own pid
            first.send_signal(signal.SIGCONT)
            first.kill()
            first.wait()
    with sqlite3.connect(database) as conn:
        completed = conn.execute("SELECT interaction FROM trials WHERE outcome = 'completed'"
                                 ).fetchall()
        resumed = conn.execute("SELECT count(*) FROM events WHERE kind = 'session_resumed'"
                               ).fetchone()[0]
    interactions = (SHORT_PROTOCOL["initial_trials"] + SHORT_PROTOCOL["learning_batches"]
                    * SHORT_PROTOCOL["batch_size"] + SHORT_PROTOCOL["best_trials"]
                    + 2 * SHORT_PROTOCOL["validation_batches"])
    assert len(completed) == len(set(completed)) == interactions
    assert resumed == 0  # the refused writers wrote nothing
    assert main(["doctor", str(study)]) == 0
    assert "P09.sqlite: OK" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.soak
def test_serve_holding_a_participant_refuses_run_session(tmp_path):
    """Starts ``handover serve`` with a participant open (its rig and its learner, torch
    included) and a ``run-session`` beside it: 10-20 s on a loaded machine."""
    study = tmp_path / "study"
    log = tmp_path / "serve.log"
    with log.open("w") as out:
        serve = subprocess.Popen(_serve(study, "--participant", "P10", "--scenario", "perturbed",
                                        "--seed", "8"), stdout=out, stderr=subprocess.STDOUT)
    try:
        wait_for(lambda: running(serve, log) and "dashboard token" in log.read_text(),
                 "serve to print its dashboard token (participant P10 open)",
                 seen=lambda: tail(log.read_text()))
        # serve is held while the second writer tries: its own worker plans the first θ in the
        # background after the token is printed, and that event is not the refused writer's. The
        # signal takes hold after kill() returns (a commit of serve's landed after it: assert 4 ==
        # 3, three times), so the events are counted once every thread of serve has stopped.
        serve.send_signal(signal.SIGSTOP)
        wait_for(lambda: stopped(serve.pid), "every thread of serve stopped by SIGSTOP",
                 seen=lambda: thread_states(serve.pid))
        before = events(study / "P10.sqlite")
        refused = subprocess.run([*HANDOVER, "run-session", "--study", str(study), "--participant",
                                  "P10", "--auto", "--resume", "--no-progress"],
                                 capture_output=True, text=True, timeout=120)
        after = events(study / "P10.sqlite")  # still held: the plan it resumes is its own
        serve.send_signal(signal.SIGCONT)
        assert refused.returncode == 2
        assert f"open for writing by pid {serve.pid} on " in refused.stderr
        assert "serve --study" in refused.stderr
        assert after == before, f"written while serve was held: {after[len(before):]}"
    finally:
        serve.send_signal(signal.SIGCONT)  # held above; a failed assertion may leave it stopped
        serve.send_signal(signal.SIGINT)
        try:
            code = serve.wait(CEILING_S)  # a ceiling for a hung shutdown, not a measurement
        except subprocess.TimeoutExpired:
            serve.kill()  # by its own pid: a hung serve must not outlive the test
            serve.wait()
            raise AssertionError(f"serve did not close within {CEILING_S:g} s of SIGINT; its log: "
                                 f"{tail(log.read_text())}") from None
    assert code == 0, log.read_text()
