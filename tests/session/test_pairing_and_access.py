"""One tablet per session and the dashboard's token, without a browser: the pairing's rules, the
token kept in the study folder, and a real runner that refuses Start without exactly one paired
tablet and after STOP ARM until Re-arm."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe

from app.protocol.errors import RefusedAction
from app.session.access import (
    DASHBOARD_BROWSERS_FILE,
    TABLET_BROWSER_FILE,
    TOKEN_FILE,
    KnownBrowsers,
    UnsafeTokenFile,
    check_access_files,
    dashboard_token,
)
from app.session.config import LabConfig
from app.session.pairing import CODE_GUESSES, WRONG_CODE_ALERT_S, TabletPairing
from app.session.runner import SessionRunner
from app.ui.status_text import status_line
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario


def test_a_page_is_the_tablet_only_once_the_code_is_typed_and_stays_it_across_a_reload():
    pairing = TabletPairing(code="4711")
    pairing.connected(1, "10.0.0.5")
    assert pairing.role(1) == "pair" and not pairing.status().ready
    assert pairing.pair(1, "1234") == "Wrong code."
    assert pairing.pair(1, " 4711 ") is None
    assert pairing.role(1) == "tablet" and pairing.status().ready
    pairing.connected(2, "10.0.0.5")  # a second tab on the same tablet: not in use
    assert pairing.role(2) == "unused"
    assert pairing.status().blocker() == ("2 pages are open on the tablet port: close all but the "
                                          "participant's tablet")
    pairing.closed(1)  # the tablet reloads: its new page is the tablet without a code
    assert pairing.role(2) == "tablet" and pairing.status().ready
    pairing.connected(3, "10.0.0.9")  # another device must type the code, and then takes over
    assert pairing.role(3) == "pair"
    assert pairing.pair(3, "4711") is None
    assert pairing.role(3) == "tablet" and pairing.role(2) == "pair"


def test_wrong_codes_are_rate_limited_per_address():
    now = [0.0]
    pairing = TabletPairing(code="4711", clock=lambda: now[0])
    pairing.connected(1, "10.0.0.5")
    pairing.connected(2, "10.0.0.6")
    for _ in range(5):
        assert pairing.pair(1, "0000") == "Wrong code."
    assert pairing.pair(1, "4711").startswith("Too many wrong attempts")  # not even checked
    assert pairing.pair(2, "4711") is None  # another address is not locked out
    now[0] = 61.0
    assert pairing.pair(1, "4711") is None


def test_guesses_from_many_addresses_replace_the_code_and_the_dashboard_says_so():
    """105 wrong codes from 21 addresses (5 each, within every address's limit) went unnoticed
    (issue 25, item 14). Now every CODE_GUESSES wrong codes, from all addresses together, replace the
    code: the old one pairs nobody, and the status line leads with what happened."""
    pairing = TabletPairing(code="4711")
    for n in range(21):
        pairing.connected(n, f"10.0.1.{n}")
        for guess in range(5):  # wrong whatever the code is (a digit guess could hit a new one)
            assert pairing.pair(n, f"x{n:02d}{guess}") == "Wrong code."
    status = pairing.status()
    assert (status.wrong_codes, status.guessers) == (105, 21)
    assert status.code_changes == 105 // CODE_GUESSES and status.code != "4711"
    pairing.connected(99, "10.0.0.5")
    assert pairing.pair(99, "4711") == "Wrong code."  # the code an attacker might have learned
    assert pairing.pair(99, status.code) is None  # the one the dashboard shows
    # 10.0.0.5's own wrong code is no alarm once it has paired; the 21 guessers' still are
    assert pairing.status().alert() == ("105 wrong pairing codes from 21 addresses; the code was "
                                        "replaced 10×")


def test_a_typo_on_the_tablet_leaves_the_alert_once_that_tablet_pairs():
    """One mistyped code left "⚠ 1 wrong pairing code from 1 address" on the dashboard until a
    restart (issue 37, item 7)."""
    pairing = TabletPairing(code="4711")
    pairing.connected(1, "10.0.0.5")
    pairing.connected(2, "10.0.0.66")
    assert pairing.pair(2, "0000") == "Wrong code."  # someone else's guess
    assert pairing.pair(1, "4771") == "Wrong code."  # the participant's typo
    assert pairing.status().alert() == "2 wrong pairing codes from 2 addresses"
    assert pairing.pair(1, "4711") is None
    assert pairing.status().alert() == "1 wrong pairing code from 1 address"  # the other one stays


def test_wrong_codes_age_out_of_the_alert():
    now = [0.0]
    pairing = TabletPairing(code="4711", clock=lambda: now[0])
    pairing.connected(1, "10.0.0.66")
    assert pairing.pair(1, "0000") == "Wrong code."
    now[0] = 300.0
    assert pairing.pair(1, "0001") == "Wrong code."
    assert pairing.status().alert() == "2 wrong pairing codes from 1 address"
    now[0] = WRONG_CODE_ALERT_S  # the first has aged out
    assert pairing.status().alert() == "1 wrong pairing code from 1 address"
    now[0] = 300.0 + WRONG_CODE_ALERT_S
    status = pairing.status()
    assert status.alert() is None and (status.wrong_codes, status.guessers) == (0, 0)


def test_a_take_over_of_the_tablet_leads_the_dashboards_status_line(tmp_path: Path):
    """Before, a second device that typed the code showed only "the tablet is paired" among the
    recent events (issue 25, item 14)."""
    runner = SessionRunner(tmp_path / "study", LabConfig(), realtime=False)
    try:
        pairing = runner.attach_tablet()
        pairing.connected(1, "10.0.0.5")
        runner.pair_tablet(1, pairing.code)
        assert runner.view.tablet.alert() is None
        pairing.connected(2, "10.0.0.66")
        runner.pair_tablet(2, pairing.code)
        view = runner.view
        assert view.tablet.taken_over_from == "10.0.0.5"
        assert status_line(view).startswith(
            "⚠ **the tablet was taken over: paired from 10.0.0.5, now 10.0.0.66 (if that is not "
            "your tablet, Stop and re-pair)** · ")
        assert any("the tablet was taken over: from 10.0.0.5 to 10.0.0.66" in m for m in view.messages)
    finally:
        runner.close()


def test_the_dashboard_token_is_kept_with_the_study_and_overridden_by_the_option(tmp_path: Path):
    study = tmp_path / "study"
    token = dashboard_token(study)
    assert len(token) >= 12 and dashboard_token(study) == token  # a restart keeps it
    assert stat.S_IMODE(os.stat(study / TOKEN_FILE).st_mode) == 0o600
    assert dashboard_token(study, "given") == "given"
    assert dashboard_token(study) == token  # --token is not stored


LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": SHORT_PROTOCOL})


@pytest.mark.slow
def test_start_needs_one_paired_tablet_and_after_a_stop_a_rearm(tmp_path: Path):
    runner = SessionRunner(tmp_path / "study", LAB)
    probe = Probe(runner)
    try:
        pairing = runner.attach_tablet()
        runner.open("P01", Scenario.STRAIGHTFORWARD)
        probe.wait(lambda v: v.step is not None and v.step.value == "ready", what="the first θ",
                   timeout=READY_CEILING_S)
        with pytest.raises(RefusedAction, match="no tablet is connected"):
            runner.start_trial()
        runner.tablet_connected(7, "127.0.0.1")
        with pytest.raises(RefusedAction, match="the tablet is not paired"):
            runner.start_trial()
        assert runner.pair_tablet(7, pairing.code) is None
        assert runner.view.tablet.ready
        runner.stop()  # no trial runs: stopped at once, and Start is locked until Re-arm
        assert runner.view.stop == "stopped"
        with pytest.raises(RefusedAction, match="the arm was stopped"):
            runner.start_trial()
        runner.rearm()
        runner.start_trial()
        probe.wait(lambda v: v.waiting_for == Stage.PREPARE, what="the cycle waits for the object")
        runner.stop()  # during a trial: "stopping" until the trial has ended, then "stopped"
        view = probe.wait(lambda v: v.stop == "stopped" and v.step.value == "ready",
                          what="the stop completed")
        assert view.trials[-1].reason == "stopped by the experimenter (Stop)"
        assert any(v.stop == "stopping" for v in probe.views)
        with pytest.raises(RefusedAction, match="the arm was stopped"):
            runner.start_trial()
        runner.rearm()
        with pytest.raises(RefusedAction, match="re-arm refused: the arm was not stopped"):
            runner.rearm()
        runner.end_session()
        assert runner.view.state is None
        [summary] = runner.view.overview
        assert (summary.code, summary.status.value, summary.detail) == (
            "P01", "paused", "ended by the experimenter")
    finally:
        runner.close()


def test_a_token_file_others_could_write_is_refused(tmp_path: Path):
    """Whoever can write the token file chooses the token: a world- or group-writable file or a
    symbolic link is refused, naming it (before, any was read)."""
    study = tmp_path / "study"
    token = dashboard_token(study)
    path = study / TOKEN_FILE
    assert path.stat().st_mode & 0o777 == 0o600
    for mode in (0o666, 0o620):
        path.chmod(mode)
        with pytest.raises(UnsafeTokenFile, match=rf"{TOKEN_FILE} is writable by others \(mode {mode:o}\)"):
            dashboard_token(study)
    assert dashboard_token(study, "given") == "given"  # --token reads no file
    path.chmod(0o600)
    assert dashboard_token(study) == token
    chosen = tmp_path / "chosen"
    chosen.write_text("attacker\n")
    chosen.chmod(0o600)
    path.unlink()
    path.symlink_to(chosen)
    with pytest.raises(UnsafeTokenFile, match="is a symbolic link"):
        dashboard_token(study)


def test_the_paired_browser_is_the_tablet_again_after_a_restart_without_the_code(tmp_path: Path):
    """A restart cost a new pairing code (issue 37, item 5): the browser that paired is kept with
    the study (hashed, owner-only) and is the tablet again when it connects, from any address."""
    study = tmp_path / "study"
    first = TabletPairing(code="4711", known=KnownBrowsers(study, TABLET_BROWSER_FILE))
    first.connected(1, "10.0.0.5", browser="a" * 32)
    assert first.pair(1, "4711") is None
    stored = (study / TABLET_BROWSER_FILE).read_text()
    assert "a" * 32 not in stored and stat.S_IMODE(os.stat(study / TABLET_BROWSER_FILE).st_mode) == 0o600
    again = TabletPairing(code="0815", known=KnownBrowsers(study, TABLET_BROWSER_FILE))  # a restart
    assert again.connected(7, "10.0.0.5", browser="b" * 32) is False  # another browser: the code
    assert again.role(7) == "pair"
    assert again.connected(8, "10.0.0.9", browser="a" * 32) is True  # the paired one, new address
    assert again.role(8) == "tablet" and again.status().taken_over_from is None
    assert again.connected(9, "10.0.0.9", browser="a" * 32) is False  # a second tab: not in use
    assert again.role(9) == "unused"


def test_known_browsers_forget_with_a_new_salt_and_refuse_a_planted_file(tmp_path: Path):
    study = tmp_path / "study"
    known = KnownBrowsers(study, DASHBOARD_BROWSERS_FILE, salt="token-1", keep=2)
    for browser in ("1" * 32, "2" * 32, "3" * 32):
        known.remember(browser)
    assert [known.known(b) for b in ("1" * 32, "2" * 32, "3" * 32)] == [False, True, True]
    assert not known.known(None)
    assert not KnownBrowsers(study, DASHBOARD_BROWSERS_FILE, salt="token-2").known("3" * 32)
    path = study / DASHBOARD_BROWSERS_FILE
    path.unlink()
    path.symlink_to(tmp_path / "elsewhere")
    with pytest.raises(UnsafeTokenFile, match="is a symbolic link"):
        check_access_files(study)
    assert not known.known("3" * 32)  # planted while serving: no browser is known by it


#: How long serve may take to refuse a planted file (its imports and the session's start) [s].
SERVE_REFUSAL_S = 120


@pytest.mark.parametrize("file", [DASHBOARD_BROWSERS_FILE, TABLET_BROWSER_FILE])
@pytest.mark.parametrize("planted", ["symlink", "mode 666"])
def test_serve_refuses_a_planted_browsers_file_before_it_prints_an_address(tmp_path, file, planted):
    """A symbolic link or a world-writable .dashboard-browsers or .tablet-browser gave every page a
    traceback and no screen, STOP ARM included, while serve printed its addresses as usual (issue
    45, item 6): refused at start with a sentence, as the token file is. (A subprocess: before the
    fix serve served on and the test ends it after SERVE_REFUSAL_S.)"""
    study = tmp_path / "study"
    study.mkdir()
    path = study / file
    if planted == "symlink":
        (tmp_path / "elsewhere").write_text("")
        path.symlink_to(tmp_path / "elsewhere")
    else:
        path.write_text("")
        path.chmod(0o666)
    try:
        result = subprocess.run([sys.executable, "-m", "app.cli", "serve", "--study", str(study),
                                 "--tablet-port", "0", "--dashboard-port", "0", "--token", "t"],
                                capture_output=True, text=True, timeout=SERVE_REFUSAL_S)
    except subprocess.TimeoutExpired as served:
        pytest.fail(f"serve did not refuse {path} within {SERVE_REFUSAL_S} s; it printed "
                    f"{served.stdout!r}")
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert "dashboard (experimenter):" not in result.stdout and "Traceback" not in result.stderr
    reason = "is a symbolic link" if planted == "symlink" else "is writable by others (mode 666)"
    assert f"handover serve: error: {path} {reason}: refused" in result.stderr, result.stderr


def test_a_browsers_file_planted_while_serving_grants_nothing_and_fails_no_page(tmp_path, caplog):
    """Planted after the start, the file is read as no known browser (each page shows its token or
    code screen: the dashboard's STOP ARM comes with the token) and the next pairing replaces it
    with the study's own owner-only file."""
    study = tmp_path / "study"
    known = KnownBrowsers(study, TABLET_BROWSER_FILE)
    known.remember("a" * 32)
    path = study / TABLET_BROWSER_FILE
    path.unlink()
    planted = tmp_path / "planted"
    planted.write_text(KnownBrowsers(tmp_path, "x")._hash("b" * 32) + "\n")
    target = planted.read_text()
    path.symlink_to(planted)
    pairing = TabletPairing(code="4711", known=known)
    assert pairing.connected(1, "10.0.0.9", browser="b" * 32) is False  # the planted id: no tablet
    assert pairing.role(1) == "pair"
    assert "is a symbolic link" in caplog.text
    assert pairing.pair(1, "4711") is None
    assert not path.is_symlink() and stat.S_IMODE(path.stat().st_mode) == 0o600
    assert planted.read_text() == target  # the link's target is untouched
    assert known.known("b" * 32)


def test_a_token_file_others_may_read_is_made_owner_only_with_a_warning(tmp_path, caplog):
    """A 0644 token file was read without a word (issue 45, item 8): it is made owner-only, as the
    writer's lock file is, and serve says that whoever read it knows the token."""
    study = tmp_path / "study"
    token = dashboard_token(study)
    path = study / TOKEN_FILE
    path.chmod(0o644)
    assert dashboard_token(study) == token
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert (f"{path} was readable by others (mode 644): made owner-only (600). Anyone who read it "
            "knows the token: delete it for a new one") in caplog.text


def test_once_the_tablets_page_closes_another_browser_of_its_address_needs_the_code():
    """After the paired tablet's page closed, another browser from the same address became the
    tablet without the code, and the dashboard advised "type the code" when the tablet itself needed
    none (issue 45, item 11). The pairing belongs to the browser that typed it (its page's id):
    that browser comes back without the code, any other types it."""
    pairing = TabletPairing(code="6715")
    pairing.connected(1, "10.0.0.5", browser="a" * 32)
    assert pairing.pair(1, "6715") is None
    pairing.connected(2, "10.0.0.5", browser="a" * 32)  # a second tab of the tablet's browser
    assert pairing.role(2) == "unused"
    pairing.closed(1)
    pairing.closed(2)
    assert pairing.status().blocker() == (
        "the paired tablet's page is closed: open the tablet page on it again (no code needed; "
        "another device types the code 6715)")
    pairing.connected(3, "10.0.0.5", browser="b" * 32)  # another browser, same address (a NAT)
    assert pairing.role(3) == "pair" and not pairing.status().ready
    assert pairing.status().blocker() == "the tablet is not paired: type the code 6715 on it"
    pairing.connected(4, "10.0.0.5", browser="a" * 32)  # the tablet's own browser, reloaded
    assert pairing.role(4) == "tablet" and pairing.role(3) == "pair"
    pairing.closed(3)
    assert pairing.status().ready
