"""Simulated populations like the paper's own: optima resampled from Tables II–III.

The 16 participants of the paper ended with the θ* of Tables II (straightforward handover) and III
(perturbed handover). Normalised by Table I's box they are anything but a cloud around one shared
optimum: most sit on the box's faces (a = 1 or 10, k = 0.01 or 15), the per-parameter standard
deviations (0.42 / 0.27 / 0.46 and 0.35 / 0.25 / 0.43) exceed a uniform draw's 0.29, and yet they
share something (six of eight straightforward participants chose the non-reactive k = 0.01).

:func:`paper_optimum` draws a simulated participant's optimum for one scenario: one of that
table's eight θ* chosen uniformly, plus N(0, ``PAPER_JITTER``²·I) in the unit cube (the tables
report learned θ*, not the participants' true optima), clipped to the cube. A population of these
is what a lab recruiting like the paper would meet; ``participant_target(..., spread="paper")``
uses it, population p drawing from the table of scenario p mod 2.
"""

from __future__ import annotations

from typing import Final, Literal

import numpy as np

from robot_io.theta import THETA_BOUNDS

#: The ``spread`` that selects this population (``--spread paper``).
PAPER_POPULATION: Final = "paper"
PaperPopulation = Literal["paper"]

#: θ* = (a_d, δ_d, k) of Tables II (straightforward) and III (perturbed), in Table I's units.
PAPER_OPTIMA: Final[tuple[tuple[tuple[float, float, float], ...], ...]] = (
    ((1.00, 0.29, 0.01), (10.00, -0.80, 0.01), (6.06, -1.00, 0.01), (1.00, 0.40, 0.01),
     (6.82, -0.52, 0.01), (10.00, -1.00, 0.01), (4.81, -0.48, 15.0), (10.0, -0.33, 15.0)),
    ((1.00, -0.20, 0.01), (10.00, -0.51, 12.83), (4.19, -1.0, 0.01), (10.00, 0.04, 15.0),
     (8.50, 0.17, 4.16), (6.77, 0.55, 2.52), (4.18, -0.11, 9.93), (7.49, 0.43, 15.0)),
)

#: Standard deviation (unit cube, per parameter) of a simulated optimum around the table's θ*.
PAPER_JITTER: Final = 0.05


def paper_optima_unit(scenario: int) -> np.ndarray:
    """The eight θ* of scenario ``scenario`` (0: Table II, 1: Table III) in the unit cube of Table I."""
    low = np.array([THETA_BOUNDS[n][0] for n in ("a", "delta", "k")])
    high = np.array([THETA_BOUNDS[n][1] for n in ("a", "delta", "k")])
    return (np.array(PAPER_OPTIMA[scenario]) - low) / (high - low)


def paper_optimum(rng: np.random.Generator, scenario: int, dim: int) -> np.ndarray:
    """One simulated participant's optimum for ``scenario``: a table row plus jitter, clipped."""
    if dim != 3:
        raise ValueError(f"spread = {PAPER_POPULATION!r} needs dim = 3 (θ = a, δ, k), not {dim}")
    rows = paper_optima_unit(scenario)
    row = rows[rng.integers(len(rows))]
    return np.clip(row + rng.normal(0.0, PAPER_JITTER, size=dim), 0.0, 1.0)
