"""UR5 forward kinematics against poses computed by hand from the DH table, and the analytic inverse
against the forward kinematics on Hypothesis-drawn joint angles."""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robot_io.arms.ur_kinematics import (
    A,
    D,
    forward,
    inverse,
    link_points,
    nearest_inverse,
    pose_to_transform,
    transform_to_pose,
)

d1, a2, a3, d4, d5, d6 = D[0], A[1], A[2], D[3], D[4], D[5]
angle = st.floats(-np.pi, np.pi, allow_nan=False)
joint_angles = st.lists(angle, min_size=6, max_size=6).map(np.array)


def regular(q: np.ndarray) -> bool:
    """q is away from the UR5's singularities: sin q5 = 0 (wrist), sin q3 = 0 (elbow stretched),
    the wrist centre within d4 of the base axis (shoulder)."""
    tcp = forward(q)
    wrist = tcp[:3, 3] - d6 * tcp[:3, 2]
    return abs(np.sin(q[4])) > 1e-3 and abs(np.sin(q[2])) > 1e-3 and \
        np.hypot(wrist[0], wrist[1]) > d4 + 1e-3


def test_the_zero_pose_is_the_ur5s_stretched_arm_along_minus_x():
    """q = 0: flange at (a2 + a3, −(d4 + d6), d1 − d5) = (−0.81725, −0.19145, −0.005491), tool z along
    −y (what a UR5 reports at zero: rotation vector (π/2, 0, 0))."""
    tcp = forward(np.zeros(6))
    assert np.allclose(tcp[:3, 3], [-0.81725, -0.19145, -0.005491], atol=1e-12)
    assert np.allclose(tcp[:3, 3], [a2 + a3, -(d4 + d6), d1 - d5], atol=1e-12)
    assert np.allclose(transform_to_pose(tcp)[3:], [np.pi / 2, 0.0, 0.0], atol=1e-12)


def test_the_upright_pose_stacks_the_links_on_the_base_axis():
    """q = (0, −π/2, 0, −π/2, 0, 0): shoulder, elbow and wrist 1 on the base axis at heights d1,
    d1 − a2, d1 − a2 − a3; then d4 and d6 sideways (−y) and d5 up."""
    points = link_points(np.array([0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0]))
    expected = [[0, 0, 0], [0, 0, d1], [0, 0, d1 - a2], [0, 0, d1 - a2 - a3],
                [0, -d4, d1 - a2 - a3], [0, -d4, d1 - a2 - a3 + d5], [0, -d4 - d6, d1 - a2 - a3 + d5]]
    assert np.allclose(points, expected, atol=1e-12)


def test_link_points_take_many_rows_and_give_nan_for_missing_angles():
    q = np.array([np.zeros(6), np.full(6, np.nan), [0.3, -1.2, 1.1, -0.4, 0.9, 0.2]])
    points = link_points(q)
    assert points.shape == (3, 7, 3)
    assert np.allclose(points[0], link_points(np.zeros(6)))
    assert np.all(np.isnan(points[1, 1:]))
    assert np.allclose(points[2, -1], forward(q[2])[:3, 3])


@settings(max_examples=300, deadline=None)
@given(joint_angles)
def test_every_inverse_solution_reaches_the_pose_and_the_nearest_is_the_drawn_q(q):
    """For a pose reached by a regular q, every solution's FK is the pose within 1e-6 m and 1e-6
    (rotation matrix entries), and the solution nearest q is q."""
    assume(regular(q))
    tcp = forward(q)
    pose = transform_to_pose(tcp)
    solutions = inverse(pose_to_transform(pose))
    assert 1 <= len(solutions) <= 8
    for solution in solutions:
        reached = forward(solution)
        assert np.linalg.norm(reached[:3, 3] - tcp[:3, 3]) < 1e-6
        assert np.abs(reached[:3, :3] - tcp[:3, :3]).max() < 1e-6
    assert np.allclose(nearest_inverse(pose, q), q, atol=1e-6)


@settings(max_examples=100, deadline=None)
@given(joint_angles, st.lists(st.sampled_from([-1, 0, 1]), min_size=6, max_size=6).map(np.array))
def test_the_nearest_solution_follows_joints_beyond_pi_without_a_jump(q, turns):
    """A UR's joints turn ±2π: seeded with q + 2π·turns, the solution is q + 2π·turns, not q."""
    assume(regular(q))
    seed = q + 2 * np.pi * turns
    assert np.allclose(nearest_inverse(transform_to_pose(forward(q)), seed), seed, atol=1e-6)


def test_a_pose_out_of_reach_has_no_solution():
    assert nearest_inverse(np.array([1.2, 0.0, 0.3, 0.0, np.pi, 0.0]), np.zeros(6)) is None
    assert len(inverse(pose_to_transform(np.array([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])))) == 0
