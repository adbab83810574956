"""Seeds: validated before anything is written, fresh by default, never silently shared."""

from __future__ import annotations

import subprocess
import sys

import pytest
from pydantic import ValidationError
from support.engine import BRIEF_PROTOCOL, SESSION_LOOP_TOML, new_engine, protocol_toml, short_config
from support.store import event_count
from support.waiting import CEILING_S, wait_for

from app.cli import main
from app.protocol.errors import RefusedAction
from app.protocol.seeds import SEED_MAX, choose_seed, seeds_in_use
from app.session.config import LabConfig
from robot_io.hands.simulated_hand import Scenario


@pytest.mark.parametrize("command", ["run-session", "serve"])
@pytest.mark.parametrize("seed, shown", [("99999999999999999999999", "99999999999999999999999"),
                                         ("-1", "-1"), ("1.5", "'1.5'")])
def test_a_bad_seed_is_refused_with_field_and_range_and_nothing_is_created(
        tmp_path, capsys, command, seed, shown):
    study = tmp_path / "study"
    argv = [command, "--study", str(study), "--participant", "P01", "--scenario", "perturbed",
            f"--seed={seed}", *(["--auto"] if command == "run-session" else [])]
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"seed = {shown}" in err and str(SEED_MAX) in err
    assert not study.exists()


def test_the_largest_seed_fits_the_store_and_one_beyond_it_is_refused(tmp_path):
    engine = new_engine(tmp_path, seed=SEED_MAX)
    engine.close()
    assert seeds_in_use(tmp_path) == {SEED_MAX: ["S01"]}
    with pytest.raises(ValidationError, match="seed"):
        short_config(seed=SEED_MAX + 1)


def test_new_participants_get_fresh_recorded_seeds_and_a_reused_one_needs_confirmation(tmp_path):
    lab = LabConfig()
    fresh = [choose_seed(tmp_path, None) for _ in range(20)]
    assert len(set(fresh)) == 20  # drawn from the OS's entropy, not 0 for everyone
    new_engine(tmp_path, "P01", seed=5).close()
    with pytest.raises(RefusedAction, match=r"seed = 5 is already used in .* by P01.*--reuse-seed"):
        choose_seed(tmp_path, 5)
    assert choose_seed(tmp_path, 5, reuse_confirmed=True) == 5
    assert choose_seed(tmp_path, 6) == 6
    assert lab.study_config(Scenario.PERTURBED, fresh[0]).seed == fresh[0]


def test_run_session_refuses_a_reused_seed_before_creating_anything(tmp_path, capsys):
    new_engine(tmp_path, "P01", seed=5).close()
    assert main(["run-session", "--study", str(tmp_path), "--participant", "P02", "--scenario",
                 "perturbed", "--auto", "--seed", "5", "--no-progress"]) == 2
    assert "seed = 5 is already used" in capsys.readouterr().err
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith("P02")]


@pytest.mark.slow
def test_two_new_participants_started_together_with_one_seed_are_not_both_created(tmp_path):
    """Two run-session processes create P01 and P02 with ``--seed 7`` at once: the seed's check
    and the session's creation are one step for the study folder, so one is created and the other
    refused, naming the seed and the participant that has it. (Before, each checked the seed before
    either had stored it, and both were created: issue 25, item 7.)"""
    lab, study = tmp_path / "lab.toml", tmp_path / "study"
    lab.write_text(f"{SESSION_LOOP_TOML}[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}")
    runs, logs = {}, {}
    for code in ("P01", "P02"):
        logs[code] = tmp_path / f"{code}.log"
        with logs[code].open("w") as err:
            runs[code] = subprocess.Popen(
                [sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
                 "--participant", code, "--scenario", "perturbed", "--auto", "--seed", "7",
                 "--no-progress", "--config", str(lab)], stdout=subprocess.DEVNULL, stderr=err)
    try:
        def created(code: str) -> bool:
            return event_count(study / f"{code}.sqlite") > 0

        def settled() -> str:
            return {code: "created" if created(code) else f"exit {run.poll()}"
                    for code, run in runs.items()}

        wait_for(lambda: all(created(code) or run.poll() is not None
                             for code, run in runs.items()),
                 "each run-session to create its participant or to exit", timeout=CEILING_S * 3,
                 seen=settled)
        assert sorted(settled().values()) == ["created", "exit 2"], settled()
        refused = next(code for code, run in runs.items() if run.poll() == 2)
        other = "P01" if refused == "P02" else "P02"
        assert f"seed = 7 is already used in {study} by {other}" in logs[refused].read_text()
        assert not (study / f"{refused}.sqlite").exists()
    finally:
        for run in runs.values():  # the created session's writer, by its own pid
            if run.poll() is None:
                run.kill()
                run.wait()
