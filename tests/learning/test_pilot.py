"""``handover pilot``: validation scores and the sign test's power, checked by direct computation."""

from __future__ import annotations

import csv
import json
import math

import pytest

from app.cli import main
from app.learning.pilot import sign_test_p


def direct_sign_test(scores: list[float]) -> float:
    """P(K ≥ k) for K ~ Bin(n, ½), n the untied scores, k those above 50 %: by hand."""
    above = sum(s > 0.5 for s in scores)
    n = above + sum(s < 0.5 for s in scores)
    if n == 0:
        return 1.0
    return sum(math.comb(n, k) for k in range(above, n + 1)) / 2**n


def test_the_papers_validation_scores_give_its_p_value():
    """Tables II–III: 15 of 16 participants above 50 %, one at 50 % (a tie, dropped)."""
    scores = [1, .75, .75, 1, .75, .75, 1, 1, .5, 1, 1, 1, .75, 1, .75, 1]
    assert sign_test_p(scores) == pytest.approx(2.0**-15)
    assert sign_test_p(scores) < 0.001
    for scores in ([0.75, 0.25, 1.0, 0.0, 0.5], [0.25] * 4, [0.5, 0.5], [1.0] * 5 + [0.0]):
        assert sign_test_p(scores) == pytest.approx(direct_sign_test(scores))


def test_pilot_power_matches_a_direct_computation_from_its_rows(tmp_path, capsys, on_the_cluster):
    """Slow: the power curve needs studies of participants: 3 studies × 2 scenarios × 3 simulated
    participants, each learning with the real learner, the smallest pilot with a curve to check."""
    out = tmp_path / "pilot"
    args = ["pilot", "--studies", "3", "--participants", "3", "--scenarios", "2",
            "--noise", "0.2", "--initial", "3", "--batches", "1", "--batch-size", "3",
            "--seed", "5", "--out", str(out), "--no-progress", "--json", *on_the_cluster]
    assert main(args) == 0
    report = json.loads(capsys.readouterr().out)
    with (out / "participants.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 3 * 2 * 3
    for row in rows:
        assert float(row["score"]) == int(row["wins"]) / int(row["pairs"]) and row["pairs"] == "4"
    for estimate in report["power_curve"]:
        n, alpha = estimate["participants_per_scenario"], estimate["alpha"]
        significant = sum(
            direct_sign_test([float(r["score"]) for r in rows
                              if int(r["study"]) == study and int(r["participant"]) < n]) < alpha
            for study in range(3))
        assert estimate["significant"] == significant
        assert estimate["power"] == pytest.approx(significant / 3)
        # Clopper–Pearson: the exact binomial bounds at 2.5 % each side
        if 0 < significant < 3:
            assert estimate["ci_low"] < significant / 3 < estimate["ci_high"]
        assert (estimate["ci_low"] == 0.0) == (significant == 0)
        assert (estimate["ci_high"] == 1.0) == (significant == 3)
    assert [p["alpha"] for p in report["power"]] == [0.05, 0.001]
    shares = report["score_distribution"]
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["100%"] == pytest.approx(sum(r["wins"] == "4" for r in rows) / len(rows))
    assert (out / "pilot.png").stat().st_size < 200_000
    # a second run with more studies resumes: the first three studies' rows are not rerun
    before = (out / "participants.csv").read_text()
    assert main([*args[:2], "4", *args[3:]]) == 0
    after = (out / "participants.csv").read_text()
    assert after.startswith(before) and len(after.splitlines()) == 1 + 4 * 6


def test_pilot_with_ties_modelled_and_learning_that_stops_when_settled(tmp_path, capsys,
                                                                     on_the_cluster):
    """Issue 40 in the pilot: each row says how many interactions learning used (a batch end
    from the second learning batch on, or the whole schedule) and how many ties it modelled."""
    out = tmp_path / "pilot"
    args = ["pilot", "--studies", "1", "--participants", "3", "--scenarios", "1", "--noise", "0.05",
            "--initial", "3", "--batches", "3", "--batch-size", "3", "--tie", "0.3", "--ties",
            "model", "--stop-when-settled", "0.5", "--seed", "5", "--out", str(out),
            "--no-progress", "--json", *on_the_cluster]
    assert main(args) == 0
    report = json.loads(capsys.readouterr().out)
    with (out / "participants.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    used = [int(r["learning_interactions"]) for r in rows]
    assert set(used) <= {9, 12}  # 3 + 2 batches of 3, or the whole 3 + 3 batches of 3
    assert report["median_learning_interactions"] == pytest.approx(sorted(used)[1])
    assert sum(int(r["ties"]) for r in rows) > 0  # "equal" within 0.3 happens, and is modelled
    assert report["config"]["stopping"]["threshold"] == 0.5


def test_pilot_with_coactive_hints_counts_them_per_participant(tmp_path, capsys, on_the_cluster):
    """--coactive: each row says how many hints the participant gave; the summary their mean."""
    out = tmp_path / "pilot"
    assert main(["pilot", "--studies", "1", "--participants", "2", "--scenarios", "1", "--noise",
                 "0.05", "--initial", "3", "--batches", "1", "--batch-size", "3", "--coactive",
                 "--seed", "5", "--out", str(out), "--no-progress", *on_the_cluster]) == 0
    with (out / "participants.csv").open() as handle:
        hints = [int(r["hints"]) for r in csv.DictReader(handle)]
    assert len(hints) == 2 and sum(hints) > 0  # uniform optima: some way feels better somewhere
    assert f"; {sum(hints) / 2:.1f} hints per participant" in capsys.readouterr().out
    assert json.loads((out / "pilot.json").read_text())["coactive"] is True
