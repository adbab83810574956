"""The posterior slices through θ* that the dashboard draws."""

from __future__ import annotations

import numpy as np

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox


def test_slices_peak_near_the_target_the_comparisons_point_to():
    """Slow (~20 s in a loaded full run): 25 suggestions of the preference learner, each a fit of
    the GP and an acquisition optimisation, before the slices are read."""
    box = ParameterBox.from_bounds({"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)})
    target = np.array([0.8, 0.25, 0.6])  # in the unit cube
    learner = PreferenceLearner(LearnerConfig(box=box, seed=3))
    assert learner.posterior_slices() == []  # no model before the first comparison
    seen: list[tuple[str, float]] = []
    for n in range(1, 26):
        theta = learner.suggest().theta
        unit = np.array(box.to_unit(theta))
        utility = -float(np.linalg.norm(unit - target))
        iid = str(n)
        comparisons = [Comparison(winner=iid, loser=j) if utility > u else
                       Comparison(winner=j, loser=iid) for j, u in seen[-4:]]
        learner.observe(Interaction(interaction_id=iid, theta=theta), comparisons)
        seen.append((iid, utility))
    slices = learner.posterior_slices()
    assert [s.parameter for s in slices] == ["a", "delta", "k"]
    best = learner.best().theta
    for s, (low, high), coordinate in zip(slices, zip(box.lower, box.upper, strict=True), target,
                                          strict=True):
        assert len(s.values) == len(s.mean) == len(s.std) == 41
        assert s.values[0] == low and s.values[-1] == high
        assert np.all(np.isfinite(s.mean)) and np.all(np.asarray(s.std) >= 0)
        peak = (s.values[int(np.argmax(s.mean))] - low) / (high - low)
        assert abs(peak - coordinate) < 0.3, (s.parameter, peak, coordinate)
        # the slice passes through θ*: its other parameters are θ*'s
        assert min(abs(v - best[s.parameter]) for v in s.values) <= (high - low) / 40
