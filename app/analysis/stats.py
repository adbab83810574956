"""The statistical tests of Sect. VI: sign tests against a threshold and Mann–Whitney U between the
scenarios. Each returns a :class:`StatTest` that states N, the statistic, p, the sidedness and how ties
were treated, so a table of them reads like the paper's "(Sign test, N = 16, p < 0.001)".

Sign test (Sect. VI-A, VI-B): each value above the threshold is a "+", below a "−". Values exactly at
the threshold (a validation score of 50 %, a Likert answer of 3) carry no sign and are dropped before
the test, the standard rule (Dixon & Mood 1946); N is then the number of signs. Under H0 the "+" count
is Binomial(N, ½); p is its exact tail (``scipy.stats.binomtest``).

Mann–Whitney U (Sect. VI-B): two-sided; with tied ranks (Likert answers always have them) the exact
null distribution does not apply, so p comes from the normal approximation with the tie-corrected
variance and a continuity correction (``scipy.stats.mannwhitneyu(method="asymptotic")``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field
from scipy import stats

from app.analysis.tables import SCENARIOS
from session_store.vocabulary import questions

Alternative = Literal["greater", "less", "two-sided"]

SIGN_TIE_RULE = "values at the threshold carry no sign and are dropped (N counts the signs)"
MWU_METHOD = "normal approximation, tie-corrected variance, continuity correction"


class StatTest(BaseModel):
    """One hypothesis test as reported: what was tested, on how many, with what result."""

    model_config = ConfigDict(frozen=True)

    name: str = Field(description="what is tested, e.g. 'validation score > 50 %'")
    test: Literal["sign", "mann-whitney-u"]
    alternative: Alternative = Field(description="sidedness of H1")
    n_total: int = Field(description="observations given (all groups)")
    n: int = Field(description="observations the test used (sign test: ties at the threshold "
                               "dropped)")
    n_ties: int = Field(description="sign test: values at the threshold; Mann–Whitney: values "
                                    "sharing a rank with another")
    groups: dict[str, int] = Field(description="sign test: counts above / below the threshold; "
                                               "Mann–Whitney: size of each group")
    statistic: float = Field(description="sign test: number of values above the threshold; "
                                         "Mann–Whitney: U of the first group")
    p_value: float
    method: str = Field(description="how p is computed and how ties are treated")

    def significant(self, alpha: float = 0.05) -> bool:
        return self.p_value < alpha

    def statistic_text(self) -> str:
        """The statistic as reported ("n/a" without the data for it: one group, no signs)."""
        return "n/a" if math.isnan(self.statistic) else f"{self.statistic:g}"

    def p_text(self) -> str:
        """p as reported: two significant digits, scientific below 1e-4, "n/a" without data."""
        p = self.p_value
        return "n/a" if math.isnan(p) else f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}"

    def summary(self) -> str:
        """The result in the paper's style, e.g. ``Sign test, N=15, S=15, p=3.1e-05 (greater)``,
        in the words of the report's page ("n/a" where there is no result)."""
        label = "Sign test" if self.test == "sign" else "Mann-Whitney U test"
        symbol = "S" if self.test == "sign" else "U"
        return (f"{label}, N={self.n}, {symbol}={self.statistic_text()}, p={self.p_text()} "
                f"({self.alternative})")


def _finite(values: Iterable[float]) -> np.ndarray:
    array = np.asarray(list(values), dtype=float)
    return array[np.isfinite(array)]


def sign_test(values: Iterable[float], threshold: float, name: str,
              alternative: Alternative = "greater") -> StatTest:
    """Sign test of ``values`` against ``threshold`` (missing values ignored, ties dropped).

    ``alternative="greater"``: H1 is that values tend to lie above the threshold, the paper's
    directional hypotheses (learned θ preferred over Sobol θ; Q1 answers above 3).
    """
    data = _finite(values)
    above, below = int(np.sum(data > threshold)), int(np.sum(data < threshold))
    n = above + below
    p = stats.binomtest(above, n, 0.5, alternative=alternative).pvalue if n else float("nan")
    return StatTest(name=name, test="sign", alternative=alternative, n_total=len(data), n=n,
                    n_ties=len(data) - n, groups={"above": above, "below": below},
                    statistic=above, p_value=float(p), method=f"exact binomial; {SIGN_TIE_RULE}")


def mann_whitney(x: Iterable[float], y: Iterable[float], name: str, labels: tuple[str, str],
                 alternative: Alternative = "two-sided") -> StatTest:
    """Mann–Whitney U test between two independent groups (``labels`` name them, ``x`` first)."""
    first, second = _finite(x), _finite(y)
    pooled = np.concatenate([first, second])
    _, counts = np.unique(pooled, return_counts=True)
    if len(first) and len(second):
        result = stats.mannwhitneyu(first, second, alternative=alternative, method="asymptotic")
        statistic, p = float(result.statistic), float(result.pvalue)
    else:
        statistic, p = float("nan"), float("nan")
    return StatTest(name=name, test="mann-whitney-u", alternative=alternative, n_total=len(pooled),
                    n=len(pooled), n_ties=int(counts[counts > 1].sum()),
                    groups={labels[0]: len(first), labels[1]: len(second)}, statistic=statistic,
                    p_value=p, method=MWU_METHOD)


def paper_tests(scores: pd.DataFrame, survey: pd.DataFrame) -> list[StatTest]:
    """The tests of Sect. VI over the participants whose session is complete: the validation
    score's sign test, then per question of the questionnaire a sign test where it states a
    hypothesis (``above``: Q1 > 3) and, for a numeric question, Mann–Whitney U between the
    scenarios (Q1, Q3) — the paper's four tests for its three questions.

    ``scores``: Tables II–III (``tables.validation_scores``), ``survey``: Table IV
    (``tables.survey_table``); both with ``scenario`` and ``complete`` columns. Incomplete sessions
    are left out of every test (the report lists them).
    """
    scores = scores[scores["complete"]]
    survey = survey[survey["complete"]]
    first, second = SCENARIOS

    def by_scenario(question: str) -> tuple[pd.Series, pd.Series]:
        return tuple(survey.loc[survey["scenario"] == s, question].astype(float) for s in SCENARIOS)

    tests = [sign_test(scores["score_pct"], 50.0, "validation score > 50 % (Tables II–III)")]
    for q in questions():
        if q.numeric and q.above is not None:
            tests.append(sign_test(survey[q.id].astype(float), q.above,
                                   f"{q.id} answers > {q.above:g} (Table IV)"))
        if q.numeric:
            tests.append(mann_whitney(*by_scenario(q.id), f"{q.id}: straightforward vs perturbed",
                                      (first, second)))
    return tests
