"""The statistical tests of Sect. VI: sign tests against a threshold and Mann–Whitney U between the
scenarios; with a within-subjects study plan, Wilcoxon's signed-rank test between each person's
sessions instead of Mann–Whitney, and the sign tests over persons. Each returns a :class:`StatTest`
that states N, the statistic, p, the sidedness and how ties were treated, so a table of them reads
like the paper's "(Sign test, N = 16, p < 0.001)".

Sign test (Sect. VI-A, VI-B): each value above the threshold is a "+", below a "−". Values exactly at
the threshold (a validation score of 50 %, a Likert answer of 3) carry no sign and are dropped before
the test, the standard rule (Dixon & Mood 1946); N is then the number of signs. Under H0 the "+" count
is Binomial(N, ½); p is its exact tail (``scipy.stats.binomtest``).

Mann–Whitney U (Sect. VI-B): two-sided; with tied ranks (Likert answers always have them) the exact
null distribution does not apply, so p comes from the normal approximation with the tie-corrected
variance and a continuity correction (``scipy.stats.mannwhitneyu(method="asymptotic")``).

Wilcoxon signed-rank (a within-subjects plan: each person ran every scenario, so the scenarios are
not independent groups): two-sided, on each person's difference between their two sessions; a zero
difference carries no sign and is dropped (Wilcoxon's rule, as the sign test's), and the ranks of
the others tie (Likert answers), so p comes from the normal approximation with the tie-corrected
variance and a continuity correction (``scipy.stats.wilcoxon(method="approx")``). The sign tests
take each person once: the mean of their complete sessions.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
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
WILCOXON_METHOD = ("zero differences dropped (N counts the others); " + MWU_METHOD)
#: Each test's name in the report's words.
TEST_WORDS = {"sign": "sign test", "mann-whitney-u": "Mann–Whitney U",
              "wilcoxon-signed-rank": "Wilcoxon signed-rank"}


class StatTest(BaseModel):
    """One hypothesis test as reported: what was tested, on how many, with what result."""

    model_config = ConfigDict(frozen=True)

    name: str = Field(description="what is tested, e.g. 'validation score > 50 %'")
    test: Literal["sign", "mann-whitney-u", "wilcoxon-signed-rank"]
    alternative: Alternative = Field(description="sidedness of H1")
    n_total: int = Field(description="observations given (all groups)")
    n: int = Field(description="observations the test used (sign test: ties at the threshold "
                               "dropped)")
    n_ties: int = Field(description="sign test: values at the threshold; Mann–Whitney: values "
                                    "sharing a rank with another; Wilcoxon: zero differences")
    groups: dict[str, int] = Field(description="sign test: counts above / below the threshold; "
                                               "Mann–Whitney: size of each group; Wilcoxon: "
                                               "the persons higher in each scenario")
    statistic: float = Field(description="sign test: number of values above the threshold; "
                                         "Mann–Whitney: U of the first group; Wilcoxon: the "
                                         "smaller of the two signed rank sums")
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
        label, symbol = {"sign": ("Sign test", "S"), "mann-whitney-u": ("Mann-Whitney U test", "U"),
                         "wilcoxon-signed-rank": ("Wilcoxon signed-rank test", "W")}[self.test]
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


def wilcoxon_paired(x: Iterable[float], y: Iterable[float], name: str, labels: tuple[str, str],
                    alternative: Alternative = "two-sided") -> StatTest:
    """Wilcoxon's signed-rank test on the paired differences ``x − y`` (one pair per person; a pair
    with a missing value is left out, a zero difference dropped); ``labels`` name the two."""
    pairs = np.column_stack([np.asarray(list(x), dtype=float), np.asarray(list(y), dtype=float)])
    pairs = pairs[np.isfinite(pairs).all(axis=1)]
    differences = pairs[:, 0] - pairs[:, 1]
    higher, lower = int(np.sum(differences > 0)), int(np.sum(differences < 0))
    if higher + lower:
        result = stats.wilcoxon(differences, zero_method="wilcox", correction=True,
                                alternative=alternative, method="approx")
        statistic, p = float(result.statistic), float(result.pvalue)
    else:
        statistic, p = float("nan"), float("nan")
    return StatTest(name=name, test="wilcoxon-signed-rank", alternative=alternative,
                    n_total=len(pairs), n=higher + lower, n_ties=len(pairs) - higher - lower,
                    groups={f"{labels[0]} higher": higher, f"{labels[1]} higher": lower},
                    statistic=statistic, p_value=p, method=WILCOXON_METHOD)


def per_person(frame: pd.DataFrame, column: str, persons: Mapping[str, int]) -> pd.Series:
    """``column`` of ``frame`` (one row per participant's session) as one value per person: the
    mean of their sessions'."""
    return frame[column].astype(float).groupby(frame["participant"].map(persons)).mean()


def paired_by_person(frame: pd.DataFrame, column: str, persons: Mapping[str, int]
                     ) -> tuple[pd.Series, pd.Series]:
    """``column`` of each person's session in the first and in the second scenario, aligned by
    person (a person without a session in one of them has a missing value there)."""
    table = frame.assign(person=frame["participant"].map(persons)).pivot_table(
        index="person", columns="scenario", values=column, aggfunc="mean")
    table = table.reindex(columns=list(SCENARIOS))
    return table[SCENARIOS[0]].astype(float), table[SCENARIOS[1]].astype(float)


def paper_tests(scores: pd.DataFrame, survey: pd.DataFrame,
                persons: Mapping[str, int] | None = None) -> list[StatTest]:
    """The tests of Sect. VI over the participants whose session is complete: the validation
    score's sign test, then per question of the questionnaire a sign test where it states a
    hypothesis (``above``: Q1 > 3) and, for a numeric question, Mann–Whitney U between the
    scenarios (Q1, Q3) — the paper's four tests for its three questions.

    ``scores``: Tables II–III (``tables.validation_scores``), ``survey``: Table IV
    (``tables.survey_table``); both with ``scenario`` and ``complete`` columns. Incomplete sessions
    are left out of every test (the report lists them). ``persons`` (participant → person: a
    within-subjects plan): the sign tests take each person once (the mean of their sessions) and
    the scenarios are compared by Wilcoxon's signed-rank test, paired by person.
    """
    scores = scores[scores["complete"]]
    survey = survey[survey["complete"]]
    first, second = SCENARIOS

    def one_per(frame: pd.DataFrame, column: str) -> pd.Series:
        return frame[column].astype(float) if persons is None else per_person(frame, column, persons)

    def compared(question: str) -> StatTest:
        if persons is not None:
            return wilcoxon_paired(*paired_by_person(survey, question, persons),
                                   f"{question}: straightforward vs perturbed, paired by person",
                                   (first, second))
        x, y = (survey.loc[survey["scenario"] == s, question].astype(float) for s in SCENARIOS)
        return mann_whitney(x, y, f"{question}: straightforward vs perturbed", (first, second))

    each = "" if persons is None else ", per person"
    tests = [sign_test(one_per(scores, "score_pct"), 50.0,
                       f"validation score > 50 % (Tables II–III){each}")]
    for q in questions():
        if q.numeric and q.above is not None:
            tests.append(sign_test(one_per(survey, q.id), q.above,
                                   f"{q.id} answers > {q.above:g} (Table IV){each}"))
        if q.numeric:
            tests.append(compared(q.id))
    return tests
