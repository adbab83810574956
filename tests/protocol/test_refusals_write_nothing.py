"""Nothing is written by a refused command (issue 15): run-session's refusals read the stored session
without migrating, resuming or touching it; report and export refuse before their first file."""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import pytest
from support.engine import drive_until, new_engine
from support.study import as_version_1, fingerprint

from app.cli import main
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario


def resume(study: Path, *extra: str) -> list[str]:
    return ["run-session", "--study", str(study), "--participant", "S01", "--auto", "--resume",
            "--no-progress", *extra]


def user_version(path: Path) -> int:
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
        return conn.execute("PRAGMA user_version").fetchone()[0]


@pytest.fixture
def older_session(tmp_path) -> Path:
    """S01 (straightforward, on the mock arm) waiting for its first placement, as schema
    version 1 wrote it: any open for writing would migrate it."""
    engine = new_engine(tmp_path / "study", scenario=Scenario.STRAIGHTFORWARD)
    drive_until(engine, Step.PLACE)
    engine.close()
    as_version_1(tmp_path / "study" / "S01.sqlite")
    return tmp_path / "study"


@pytest.mark.parametrize(("extra", "config", "message"), [
    (["--scenario", "perturbed"], "", "--scenario perturbed differs from the session's "
                                      "straightforward"),
    ([], '[arm]\nkind = "ur"\n[ur]\nhost = "127.0.0.9"\n', "was recorded on a different rig"),
])
def test_a_refused_resume_leaves_the_file_as_it_was(older_session, tmp_path, capsys, extra, config,
                                                    message):
    path = older_session / "S01.sqlite"
    before = fingerprint(path)
    lab = tmp_path / "lab.toml"
    lab.write_text(config)
    assert main(resume(older_session, *extra, "--config", str(lab))) == 2
    assert message in capsys.readouterr().err
    assert fingerprint(path) == before
    assert user_version(path) == 1  # not even migrated


def test_resuming_a_complete_session_is_refused_and_writes_nothing(tmp_path, capsys):
    engine = new_engine(tmp_path / "study")
    drive_until(engine, Step.DONE)
    engine.close()
    path = tmp_path / "study" / "S01.sqlite"
    before = fingerprint(path)
    assert main(resume(tmp_path / "study")) == 2
    assert "'S01''s session is complete (9 handovers): nothing to resume" in \
        capsys.readouterr().err
    assert fingerprint(path) == before


def test_a_refused_report_writes_no_table_or_figure(tmp_path, capsys):
    engine = new_engine(tmp_path / "study")
    drive_until(engine, Step.PLACE)
    engine.close()
    (tmp_path / "not-a-benchmark").mkdir()
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "study"), "--out", str(out), "--benchmark",
                 str(tmp_path / "not-a-benchmark")]) == 2
    assert "holds no benchmark-pl condition" in capsys.readouterr().err
    assert not out.exists()


def test_an_export_never_copies_into_the_study_folder_itself(tmp_path, capsys):
    study = tmp_path / "sqlite"  # a study folder that happens to be called 'sqlite'
    new_engine(study).close()
    before = fingerprint(study / "S01.sqlite")
    assert main(["export", str(study), "--out", str(tmp_path)]) == 2
    assert "would write its sqlite/ copies into the study folder" in capsys.readouterr().err
    assert fingerprint(study / "S01.sqlite") == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sqlite"]
