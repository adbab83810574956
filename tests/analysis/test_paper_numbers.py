"""The statistics of Sect. VI fed the paper's own Tables II–IV: they must give the paper's outcomes;
and the same tables read as a within-subjects study (each of 8 people ran both scenarios), whose
scenarios are compared paired by person.

Expected values are computed here from the formulas (binomial tail, Mann–Whitney U by counting pairs,
Wilcoxon's signed ranks, and their tie-corrected normal approximations), not copied from the
implementation's output.
"""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from app.analysis.stats import paper_tests, sign_test
from app.analysis.study_design import study_design
from app.analysis.tables import survey_table, validation_scores
from app.protocol.design import StudyPlan

# Tables II and III: participant, a_d, δ_d, k, validation %; P3's 75 is the paper's "*75".
TABLE_II_III = [
    (1, 1.00, 0.29, 0.01, 100), (2, 10.00, -0.80, 0.01, 75), (3, 6.06, -1.00, 0.01, 75),
    (4, 1.00, 0.40, 0.01, 100), (5, 6.82, -0.52, 0.01, 75), (6, 10.00, -1.00, 0.01, 75),
    (7, 4.81, -0.48, 15, 100), (8, 10, -0.33, 15, 100),
    (9, 1.00, -0.20, 0.01, 50), (10, 10.00, -0.51, 12.83, 100), (11, 4.19, -1, 0.01, 100),
    (12, 10.00, 0.04, 15, 100), (13, 8.50, 0.17, 4.16, 75), (14, 6.77, 0.55, 2.52, 100),
    (15, 4.18, -0.11, 9.93, 75), (16, 7.49, 0.43, 15, 100),
]
STARRED = {3}  # the missed pair compared two identical non-reactive controllers (Sect. VII)
# Table IV: participant, Q1, Q2, Q3
TABLE_IV = [
    (1, 4, "Maybe", 3), (2, 4, "Maybe", 4), (3, 4, "Yes", 4), (4, 3, "Yes", 4),
    (5, 5, "Maybe", 5), (6, 4, "Maybe", 4), (7, 3, "Maybe", 4), (8, 4, "No", 5),
    (9, 3, "No", 4), (10, 3, "Maybe", 4), (11, 4, "Yes", 5), (12, 4, "Yes", 4),
    (13, 3, "No", 4), (14, 4, "Maybe", 5), (15, 5, "Maybe", 5), (16, 3, "No", 4),
]
PAIRS = 4


def code(number: int) -> str:
    return f"P{number:02d}"


@pytest.fixture
def status() -> pd.DataFrame:
    return pd.DataFrame([{"participant": code(n), "complete": True,
                          "scenario": "straightforward" if n <= 8 else "perturbed"}
                         for n in range(1, 17)])


@pytest.fixture
def scores(status) -> pd.DataFrame:
    """Tables II–III rebuilt from per-pair outcomes (4 validation pairs each)."""
    pairs, stars = [], []
    for n, a, delta, k, pct in TABLE_II_III:
        won = pct * PAIRS // 100
        for i in range(PAIRS):
            pairs.append({"participant": code(n), "learned_preferred": i < won,
                          "indistinct": n in STARRED and i >= won})
        stars.append({"participant": code(n), "theta_a": a, "theta_delta": delta, "theta_k": k,
                      "utility_mean": 0.0, "after_interaction": 25})
    pairs = pd.DataFrame(pairs).astype({"learned_preferred": "boolean"})
    return validation_scores(pairs, pd.DataFrame(stars), status)


@pytest.fixture
def survey(status) -> pd.DataFrame:
    answers = pd.DataFrame([{"participant": code(n), "question": q, "value": str(v)}
                            for n, *values in TABLE_IV
                            for q, v in zip(("Q1", "Q2", "Q3"), values, strict=True)])
    return survey_table(answers, status)


def binomial_upper_tail(k: int, n: int) -> float:
    """P(X ≥ k) for X ~ Binomial(n, ½)."""
    return sum(math.comb(n, i) for i in range(k, n + 1)) / 2**n


def mann_whitney_by_hand(x: list[float], y: list[float]) -> tuple[float, float]:
    """U of x (pairs x > y plus half the ties) and the two-sided p of the normal approximation with
    tie-corrected variance and continuity correction."""
    u = sum((xi > yi) + 0.5 * (xi == yi) for xi in x for yi in y)
    n1, n2 = len(x), len(y)
    n = n1 + n2
    ties = [(x + y).count(v) for v in set(x + y)]
    variance = n1 * n2 / 12 * ((n + 1) - sum(t**3 - t for t in ties) / (n * (n - 1)))
    z = (abs(u - n1 * n2 / 2) - 0.5) / math.sqrt(variance)
    return u, math.erfc(z / math.sqrt(2))


def test_tables_ii_iii_rebuilt_from_pairs(scores):
    assert scores["score_pct"].tolist() == [row[4] for row in TABLE_II_III]
    assert scores.loc[scores["indistinct_missed"] > 0, "participant"].tolist() == ["P03"]
    assert (scores["pairs"] == PAIRS).all()


def test_validation_sign_test_reproduces_p_below_0001(scores, survey):
    result = paper_tests(scores, survey)[0]
    # P9 sits at exactly 50 %: no sign, dropped, so N = 15 signs, all "+".
    assert (result.n_total, result.n_ties, result.n) == (16, 1, 15)
    assert result.groups == {"above": 15, "below": 0} and result.statistic == 15
    assert result.alternative == "greater"
    assert result.p_value == pytest.approx(binomial_upper_tail(15, 15))
    assert result.p_value < 0.001


def test_q1_sign_test_reproduces_p_below_0001_one_sided(scores, survey):
    result = paper_tests(scores, survey)[1]
    # six answers sit at 3 (P4, P7, P9, P10, P13, P16) and are dropped: N = 10, all above
    assert (result.n_total, result.n_ties, result.n, result.statistic) == (16, 6, 10, 10)
    assert result.p_value == pytest.approx(binomial_upper_tail(10, 10))
    assert result.p_value < 0.001
    two_sided = sign_test(survey["Q1"].astype(float), 3.0, "Q1", alternative="two-sided")
    assert two_sided.p_value == pytest.approx(2 * binomial_upper_tail(10, 10))
    assert two_sided.p_value > 0.001  # the paper's p < 0.001 holds one-sided only


@pytest.mark.parametrize(("index", "question"), [(2, "Q1"), (3, "Q3")])
def test_no_significant_scenario_difference(scores, survey, index, question):
    result = paper_tests(scores, survey)[index]
    column = 1 if question == "Q1" else 3
    x = [float(row[column]) for row in TABLE_IV[:8]]
    y = [float(row[column]) for row in TABLE_IV[8:]]
    u, p = mann_whitney_by_hand(x, y)
    assert result.groups == {"straightforward": 8, "perturbed": 8} and result.n == 16
    assert result.alternative == "two-sided"
    assert result.statistic == pytest.approx(u)
    assert result.p_value == pytest.approx(p)
    assert not result.significant(0.05)


def test_incomplete_sessions_are_left_out_of_the_tests(scores, survey):
    scores.loc[scores["participant"] == "P09", "complete"] = False
    survey.loc[survey["participant"] == "P09", "complete"] = False
    validation, q1, mwu_q1, _ = paper_tests(scores, survey)
    assert (validation.n_total, validation.n_ties) == (15, 0)
    assert (q1.n_total, q1.n_ties) == (15, 5)
    assert mwu_q1.groups == {"straightforward": 8, "perturbed": 7}


#: The paper's 16 read as 8 people who ran both scenarios: person i is P0i (straightforward) and
#: P(i+8) (perturbed).
PERSONS = {code(n): (n - 1) % 8 + 1 for n in range(1, 17)}


def wilcoxon_by_hand(differences: list[float]) -> tuple[float, float]:
    """T, the smaller of the signed rank sums (zero differences dropped, tied magnitudes given their
    mean rank), and the two-sided p of the normal approximation with tie-corrected variance and
    continuity correction."""
    d = [v for v in differences if v != 0]
    n, magnitudes = len(d), sorted(abs(v) for v in d)
    rank = {m: (magnitudes.index(m) + n - 1 - magnitudes[::-1].index(m)) / 2 + 1 for m in magnitudes}
    plus = sum(rank[abs(v)] for v in d if v > 0)
    minus = sum(rank[abs(v)] for v in d if v < 0)
    ties = [magnitudes.count(m) for m in set(magnitudes)]
    variance = n * (n + 1) * (2 * n + 1) / 24 - sum(t**3 - t for t in ties) / 48
    z = (abs(min(plus, minus) - n * (n + 1) / 4) - 0.5) / math.sqrt(variance)
    return min(plus, minus), math.erfc(z / math.sqrt(2))


@pytest.mark.parametrize(("index", "column"), [(2, 1), (3, 3)])
def test_a_within_subjects_study_compares_the_scenarios_paired_by_person(scores, survey, index,
                                                                        column):
    result = paper_tests(scores, survey, PERSONS)[index]
    d = [TABLE_IV[i][column] - TABLE_IV[i + 8][column] for i in range(8)]
    t, p = wilcoxon_by_hand(d)
    assert result.test == "wilcoxon-signed-rank" and result.alternative == "two-sided"
    assert (result.n_total, result.n_ties, result.n) == (8, d.count(0), 8 - d.count(0))
    assert result.groups == {"straightforward higher": sum(v > 0 for v in d),
                             "perturbed higher": sum(v < 0 for v in d)}
    assert result.statistic == pytest.approx(t) and result.p_value == pytest.approx(p)
    assert "paired by person" in result.name


def test_a_within_subjects_studys_sign_tests_take_each_person_once(scores, survey):
    validation, q1, _, _ = paper_tests(scores, survey, PERSONS)
    for result, values, threshold in (
            (validation, [row[4] for row in TABLE_II_III], 50.0),
            (q1, [row[1] for row in TABLE_IV], 3.0)):
        means = [(values[i] + values[i + 8]) / 2 for i in range(8)]
        above, at = sum(m > threshold for m in means), sum(m == threshold for m in means)
        assert (result.n_total, result.n_ties, result.statistic) == (8, at, above)
        assert result.p_value == pytest.approx(binomial_upper_tail(above, 8 - at))
        assert result.name.endswith(", per person")


def test_a_person_with_an_incomplete_session_is_left_out_of_the_paired_tests(scores, survey):
    survey.loc[survey["participant"] == "P09", "complete"] = False  # person 1's perturbed session
    scores.loc[scores["participant"] == "P09", "complete"] = False
    validation, q1, paired_q1, _ = paper_tests(scores, survey, PERSONS)
    assert paired_q1.n_total == 7  # person 1 has no pair
    assert validation.n_total == q1.n_total == 8  # person 1 counts once, by its complete session


def test_the_design_of_a_within_subjects_plan_names_each_participants_person():
    plan = StudyPlan(design="within", group_size=2, seed=3)
    proposals = [plan.proposal(n) for n in range(1, 5)]
    participants = pd.DataFrame([
        {"participant": f"W{n}", "created_at": f"2026-01-0{n}",
         "config": json.dumps({"scenario": a.proposed.value, "assignment": a.model_dump(mode="json")})}
        for n, a in enumerate(proposals, start=1)]
        + [{"participant": "X1", "created_at": "2026-01-09",
            "config": json.dumps({"scenario": "perturbed", "assignment": None})}])
    design = study_design(participants)
    assert design.persons == {"W1": 1, "W2": 1, "W3": 2, "W4": 2}  # X1: created without the plan
    assert "paired by person" in design.line
    between = StudyPlan(design="between", group_size=2, seed=3).proposal(1)
    assert study_design(participants.assign(config=json.dumps({
        "scenario": "perturbed", "assignment": between.model_dump(mode="json")}))).persons is None
