"""The statistics of Sect. VI fed the paper's own Tables II–IV: they must give the paper's outcomes.

Expected values are computed here from the formulas (binomial tail, Mann–Whitney U by counting pairs
and its tie-corrected normal approximation), not copied from the implementation's output.
"""

from __future__ import annotations

import math

import pandas as pd
import pytest

from app.analysis.stats import paper_tests, sign_test
from app.analysis.tables import survey_table, validation_scores

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
