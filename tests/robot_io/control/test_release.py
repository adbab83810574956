"""Force-threshold release, the k_ext compliance term, and the tool-output gripper on the stand-in."""

from __future__ import annotations

import numpy as np
import pytest

from robot_io.config import ControllerConfig, ReleaseConfig
from robot_io.control.compliance import CompliantCoupling
from robot_io.control.coupling import NoCoupling
from robot_io.control.dmp import DMP
from robot_io.control.release import ForceRelease, ReleasePhase

DT = 1 / 125


def feed(release: ForceRelease, forces: np.ndarray, in_handover: bool = True) -> int | None:
    """Index of the cycle the release fired on, or None."""
    for i, force in enumerate(forces):
        if release.update(force, in_handover):
            return i
    return None


def test_noisy_biased_force_without_a_pull_never_releases_and_a_pull_does_promptly():
    rng = np.random.default_rng(1)
    bias = np.array([12.0, -4.0, 20.0])  # a CB-series estimate is biased by the payload and pose
    noise = rng.normal(0.0, 3.0, size=(1000, 3))
    release = ForceRelease(ReleaseConfig(), DT)
    assert feed(release, bias + noise) is None
    assert release.phase is ReleasePhase.ARMED and release.baseline == pytest.approx(bias, abs=2.0)
    pull = bias + np.array([0.0, 15.0, 0.0]) + rng.normal(0.0, 3.0, size=(200, 3))
    fired = feed(release, pull)
    assert fired is not None and fired * DT < 0.15
    assert release.phase is ReleasePhase.RELEASED and feed(release, pull) is None  # fires once


def test_no_release_outside_the_handover_state_and_leaving_it_resets_the_baseline():
    release = ForceRelease(ReleaseConfig(threshold_n=10.0), DT)
    assert feed(release, np.full((200, 3), 50.0), in_handover=False) is None
    assert release.phase is ReleasePhase.IDLE
    feed(release, np.zeros((100, 3)))
    assert release.phase is ReleasePhase.ARMED
    release.update(np.zeros(3), in_handover=False)
    assert release.phase is ReleasePhase.IDLE and release.baseline is None


def test_k_ext_term_yields_to_a_steady_pull_like_a_spring_and_only_while_grasped():
    config = ControllerConfig()
    c = config.dmp
    start, goal = config.scene.point("robot_start"), config.scene.point("handover_point")
    force = {"now": np.array([3.0, -2.0, 20.0])}  # the baseline at grasp: bias only
    release = ForceRelease(ReleaseConfig(), DT)
    coupling = CompliantCoupling(NoCoupling(), lambda: force["now"], c.k_ext,
                                 lambda: release.grasped, lambda: release.baseline)
    dmp = DMP.from_minimum_jerk(start, goal, c)
    pull = np.array([6.0, 0.0, 0.0])  # below the 10 N threshold: held, not released
    for i in range(int(4.0 / DT)):
        if i == int(0.5 / DT):
            force["now"] = force["now"] + pull
        release.update(force["now"], in_handover=True)
        dmp.step(DT, coupling.update(goal))
    assert release.phase is ReleasePhase.ARMED
    # steady state of τ²ẍ = α_x β_x (g − x) + k_ext (F − F₀): x − g = k_ext (F − F₀) / (α_x β_x)
    assert dmp.x - goal == pytest.approx(c.k_ext * pull / (c.alpha_x * c.beta_x), abs=1e-3)
    for _ in range(int(4.0 / DT)):
        release.update(force["now"], in_handover=False)  # handover state left: not grasped
        dmp.step(DT, coupling.update(goal))
    assert dmp.x == pytest.approx(goal, abs=1e-3)
