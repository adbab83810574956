"""A statistical test without the data for it reads "n/a" on the terminal as on the report page."""

from __future__ import annotations

import re

from app.analysis.report_page import statistics
from app.analysis.stats import mann_whitney, sign_test


def test_a_test_without_data_says_n_a_on_the_terminal_as_on_the_page():
    """``handover report`` printed "U=nan, p=nan" where the page said "n/a" (issue 45, item 18):
    a study of one scenario has no second group to compare with."""
    one_group = mann_whitney([4, 5, 3], [], "Q1 answers differ between scenarios",
                             ("straightforward", "perturbed"))
    assert one_group.summary() == "Mann-Whitney U test, N=3, U=n/a, p=n/a (two-sided)"
    no_signs = sign_test([50.0, 50.0], 50.0, "validation score > 50 %")
    assert no_signs.summary() == "Sign test, N=0, S=0, p=n/a (greater)"
    cells = re.findall(r"<td>([^<]*)</td>", statistics([one_group, no_signs]))
    assert cells.count("n/a") == 3, cells  # U and its p, the sign test's p
    assert not any("nan" in cell for cell in cells), cells
