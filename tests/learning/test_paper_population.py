"""Simulated populations like the paper's: optima resampled from the θ* of Tables II–III."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.learning.paper_population import PAPER_JITTER, paper_optima_unit
from app.learning.simulation import participant_target


def test_the_tables_are_normalised_by_table_i():
    """Participant 2 of Table II, (a, δ, k) = (10, −0.80, 0.01), and 13 of Table III,
    (8.50, 0.17, 4.16), in the unit cube of a ∈ [1, 10], δ ∈ [−1, 1], k ∈ [0.01, 15]."""
    assert paper_optima_unit(0)[1] == pytest.approx([1.0, 0.1, 0.0])
    assert paper_optima_unit(1)[4] == pytest.approx([7.5 / 9, 1.17 / 2, 4.15 / 14.99])


@pytest.mark.parametrize("population, table", [(0, 0), (1, 1), (6, 0), (9, 1)])
def test_paper_targets_are_the_tables_optima_with_jitter(population, table):
    targets = np.array([participant_target(3, 4, population, i, "paper") for i in range(400)])
    rows = paper_optima_unit(table)
    nearest = np.linalg.norm(targets[:, None] - rows[None], axis=2)
    # within 5 standard deviations of a row of this scenario's table (clipping only shortens it)
    assert nearest.min(1).max() < 5 * PAPER_JITTER * np.sqrt(3)
    assert set(nearest.argmin(1)) == set(range(len(rows)))  # every participant of the table
    other = np.linalg.norm(targets[:, None] - paper_optima_unit(1 - table)[None], axis=2)
    assert other.min(1).mean() > 2 * nearest.min(1).mean()
    assert ((targets >= 0) & (targets <= 1)).all()
    assert (participant_target(3, 4, population, 7, "paper") == targets[7]).all()  # seeded


def test_the_paper_population_needs_the_three_parameters_of_theta():
    with pytest.raises(ValueError, match="needs dim = 3"):
        participant_target(2, 0, 0, 0, "paper")


def test_pilot_runs_the_paper_population_and_names_the_allowed_spreads(tmp_path, capsys,
                                                                      on_the_cluster):
    """Slow (~23 s in a loaded full run): ``handover pilot`` runs its simulated study (``--studies 1
    --participants 2 --scenarios 2``) through the real learner on the Dask cluster."""
    out = tmp_path / "pilot"
    args = ["pilot", "--studies", "1", "--participants", "2", "--scenarios", "2", "--initial", "3",
            "--batches", "1", "--batch-size", "3", "--spread", "paper", "--out", str(out),
            "--no-progress", "--json"]
    assert main([*args, *on_the_cluster]) == 0
    capsys.readouterr()
    assert json.loads((out / "pilot.json").read_text())["spread"] == "paper"
    with pytest.raises(SystemExit):
        main([*args[:-4], "--spread", "papr", "--out", str(tmp_path / "x")])
    assert "'papr' is not a number; allowed: a number in [0, 1] or 'paper'" in \
        capsys.readouterr().err
