"""Export round trip: tidy tables that reload in pandas with the documented dtypes and reproduce the
databases' counts; two participants export into one set of tables."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pandas as pd
import pytest
from support.engine import drive_until, short_config
from support.study import contents

from app.cli import main
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.export import DTYPES, data_dictionary, export_study, read_table

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    study = tmp_path_factory.mktemp("study")
    # P02 gives coactive hints: a table only some participants have rows in exports all the same
    for code, seed, scenario in (("P01", 1, Scenario.STRAIGHTFORWARD), ("P02", 2, Scenario.PERTURBED)):
        config = short_config(seed=seed, scenario=scenario)
        if code == "P02":
            config = config.model_copy(update={"coactive": True})
        engine = SessionEngine.create(study, code, config)
        drive_until(engine, Step.DONE, SimulatedParticipant(seed))
        engine.close()
    return study


def db_counts(study: Path) -> dict[str, dict[str, int]]:
    counts = {}
    for path in sorted(study.glob("*.sqlite")):
        with sqlite3.connect(path) as conn:
            counts[path.stem] = {table: conn.execute(f'SELECT count(*) FROM "{table}"').fetchone()[0]
                                 for table in DTYPES if table != "participants"}
    return counts


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_exported_tables_reload_with_documented_dtypes_and_counts(study, tmp_path, fmt):
    """Slow in its first parameter (~40 s in a loaded full run): it pays for the module's ``study``,
    two short sessions driven to their end through the real learner."""
    written = export_study(study, tmp_path, fmt).written
    assert set(written) == set(DTYPES)
    counts = db_counts(study)
    for table in DTYPES:
        frame = read_table(tmp_path, table)
        assert {c: str(t) for c, t in frame.dtypes.items()} == DTYPES[table], table
        assert frame["participant"].notna().all()
        having = {"P02"} if table == "hints" else {"P01", "P02"}
        assert set(frame["participant"]) == having, table
        if table != "participants":
            per = frame.groupby("participant").size().to_dict()
            assert per == {code: counts[code][table] for code in having}, table
    participants = read_table(tmp_path, "participants").set_index("participant")
    assert participants.loc["P01", "scenario"] == "straightforward"
    assert participants.loc["P02", "completed"] == 9
    for code in ("P01", "P02"):  # consistent copies of the databases
        with sqlite3.connect(tmp_path / "sqlite" / f"{code}.sqlite") as conn:
            assert conn.execute("SELECT count(*) FROM trials").fetchone()[0] == \
                counts[code]["trials"]


def test_csv_and_parquet_hold_the_same_data(study, tmp_path):
    export_study(study, tmp_path / "csv", "csv")
    export_study(study, tmp_path / "parquet", "parquet")
    for table in ("trials", "placements", "comparisons", "answers"):
        pd.testing.assert_frame_equal(read_table(tmp_path / "csv", table),
                                      read_table(tmp_path / "parquet", table), check_exact=False)


def test_an_empty_study_folder_is_an_error(tmp_path):
    (tmp_path / "study").mkdir()
    with pytest.raises(StoreError, match="holds no participant database"):
        export_study(tmp_path / "study", tmp_path / "out")


def test_export_command(study, tmp_path, capsys):
    assert main(["export", str(study), "--format", "csv", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "trials: " in out and (tmp_path / "samples.csv").exists()


def test_data_dictionary_in_docs_is_current():
    """docs/data.md embeds the dictionary generated from the models: regenerate it if this fails
    (python -c 'from session_store.export import data_dictionary; print(data_dictionary())')."""
    dictionary = data_dictionary()
    assert dictionary in (ROOT / "docs" / "data.md").read_text()
    assert "|  |" not in dictionary  # every column has a meaning


def test_run_session_cli_refusals(tmp_path, capsys):
    assert main(["run-session", "--study", str(tmp_path), "--participant", "P1",
                 "--scenario", "perturbed"]) == 2
    assert "needs --auto" in capsys.readouterr().err
    assert main(["run-session", "--study", str(tmp_path), "--participant", "../x", "--auto",
                 "--scenario", "perturbed"]) == 2
    assert "participant code '../x' is not allowed" in capsys.readouterr().err
    assert main(["run-session", "--study", str(tmp_path), "--participant", "P1", "--auto",
                 "--resume"]) == 2
    assert "has no session" in capsys.readouterr().err


@pytest.mark.parametrize("inside", [".", "export", "export/deeper"])
def test_an_export_into_the_study_folder_is_refused_and_writes_nothing(study, capsys, inside):
    """``export --out`` pointing into the study folder wrote CSVs and a sqlite/ copy of every
    participant there, overwritten on a rerun (issue 45, item 9): export never writes into a study
    folder."""
    before = contents(study)
    out = study / inside
    assert main(["export", str(study), "--out", str(out)]) == 2
    assert (f"handover export: error: --out {out} is inside the study folder {study}: export never "
            "writes into a study folder") in capsys.readouterr().err
    assert contents(study) == before
