"""UR5 kinematics: forward kinematics of the joint frames and the analytic inverse, from DH parameters.

The UR5 (CB3, "serie 3") in Universal Robots' standard Denavit–Hartenberg convention (UR CB3 user
manual, appendix "Robot DH parameters", table "UR5 serie 3"; the same values are in UR's article
"DH parameters for calculations of kinematics and dynamics")::

    joint  a [m]      d [m]      α [rad]
    1      0          0.089159   π/2
    2      −0.425     0          0
    3      −0.39225   0          0
    4      0          0.10915    π/2
    5      0          0.09465    −π/2
    6      0          0.0823     0

Frame i is reached from frame i − 1 by ``Rz(q_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)``. Frame 0 is the
robot base frame in which the controller reports the TCP pose and in which this project works; frame 6
is the tool flange, which is the TCP when no tool offset is configured (the stand-in's case). At
q = 0 the arm lies stretched along −x: flange at (a2 + a3, −(d4 + d6), d1 − d5).

The inverse is the closed-form solution of Hawkins, "Analytic Inverse Kinematics for the Universal
Robots UR-5/UR-10 Arms" (Georgia Tech, 2013), re-derived here for this frame convention (see
:func:`inverse`): up to 8 solutions (shoulder left/right × wrist up/down × elbow up/down). It is
singular where sin q5 = 0 (joint 6 parallel to joints 2–4) and where the wrist centre lies on the
base axis.

A pose is the controller's ``[x, y, z, rx, ry, rz]``: position [m] and rotation vector [rad].
"""

from __future__ import annotations

import math

import numpy as np

#: DH parameters of the UR5 (see the module docstring).
D = np.array([0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823])
A = np.array([0.0, -0.425, -0.39225, 0.0, 0.0, 0.0])
ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
#: The joints' names, in order (q[0] … q[5]).
JOINTS = ("base", "shoulder", "elbow", "wrist 1", "wrist 2", "wrist 3")
#: |sin q5| below this is the wrist singularity: q6 is not determined there.
SINGULAR = 1e-9
_COS_ALPHA, _SIN_ALPHA = np.round(np.cos(ALPHA), 15), np.round(np.sin(ALPHA), 15)


def _dh(q: np.ndarray | float, i: int) -> np.ndarray:
    """Transforms (…, 4, 4) from frame i to frame i + 1 for joint angles ``q`` (…):
    Rz(q) · Tz(d_i) · Tx(a_i) · Rx(α_i)."""
    c, s = np.cos(q), np.sin(q)
    ca, sa = _COS_ALPHA[i], _SIN_ALPHA[i]
    T = np.zeros((*np.shape(q), 4, 4))
    T[..., 0, 0], T[..., 0, 1], T[..., 0, 2], T[..., 0, 3] = c, -s * ca, s * sa, A[i] * c
    T[..., 1, 0], T[..., 1, 1], T[..., 1, 2], T[..., 1, 3] = s, c * ca, -c * sa, A[i] * s
    T[..., 2, 1], T[..., 2, 2], T[..., 2, 3], T[..., 3, 3] = sa, ca, D[i], 1.0
    return T


def joint_frames(q: np.ndarray) -> np.ndarray:
    """The base frame and frames 1 … 6 in the base frame: (…, 7, 4, 4) for ``q`` of shape (…, 6)."""
    q = np.asarray(q, dtype=float)
    frames = [np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4))]
    for i in range(6):
        frames.append(frames[-1] @ _dh(q[..., i], i))
    return np.stack(frames, axis=-3)


def forward(q: np.ndarray) -> np.ndarray:
    """The flange (TCP) transform (…, 4, 4) in the base frame for joint angles ``q`` (…, 6)."""
    return joint_frames(q)[..., -1, :, :]


def link_points(q: np.ndarray) -> np.ndarray:
    """The origins of the base frame and frames 1 … 6 (…, 7, 3): the arm as kinematic links from
    the base to the flange. Rows of ``q`` with a NaN give NaN points."""
    return joint_frames(q)[..., :3, 3]


def pose_to_transform(pose: np.ndarray) -> np.ndarray:
    """A controller pose ``[x, y, z, rx, ry, rz]`` (rotation vector) as a 4 × 4 transform."""
    from scipy.spatial.transform import Rotation  # here: the app draws links only, without scipy

    pose = np.asarray(pose, dtype=float)
    transform = np.eye(4)
    transform[:3, :3] = Rotation.from_rotvec(pose[3:6]).as_matrix()
    transform[:3, 3] = pose[:3]
    return transform


def transform_to_pose(transform: np.ndarray) -> np.ndarray:
    """A 4 × 4 transform as a controller pose ``[x, y, z, rx, ry, rz]``."""
    from scipy.spatial.transform import Rotation  # here: the app draws links only, without scipy

    return np.concatenate([transform[:3, 3], Rotation.from_matrix(transform[:3, :3]).as_rotvec()])


def inverse(transform: np.ndarray) -> np.ndarray:
    """All joint solutions (k, 6), k ≤ 8, each angle in (−π, π], that put the flange at ``transform``.

    Hawkins (2013), sect. 2, re-derived in this convention. With p the flange position, x6, y6, z6
    its axes, p5 = p − d6 z6 the wrist centre, and z1 = (sin q1, −cos q1, 0) the axis shared by joints
    2–4 (frame 1's axes are x1 = (cos q1, sin q1, 0), y1 = (0, 0, 1), z1):

    * q1: the wrist centre lies d4 off the plane of joints 2–4, p5·z1 = d4, so with p5 = r(cos ψ,
      sin ψ, ·): q1 = ψ + π/2 ± acos(d4 / r);
    * q5: the flange lies d4 + d6 cos q5 off it, p·z1 = d4 + d6 cos q5: q5 = ± acos((p·z1 − d4)/d6);
    * q6: z1 seen from the flange frame is (sin q5 cos q6, −sin q5 sin q6, cos q5), so
      q6 = atan2(−(y6·z1)/sin q5, (x6·z1)/sin q5) (q6 = 0 where sin q5 = 0: it is not determined);
    * frame 4, seen from the flange frame, has x4 = (cos q5 cos q6, −cos q5 sin q6, −sin q5) and
      z4 = (−sin q6, −cos q6, 0), so its origin is p4 = p − d6 z6 + d5 (sin q6 x6 + cos q6 y6);
    * q2, q3, q4: p4 − (0, 0, d1) in frame 1 is (a2 cos q2 + a3 cos q23, a2 sin q2 + a3 sin q23, d4),
      a planar two-link arm: cos q3 by the law of cosines (± its acos), q2 from the angles of the
      point and of the links, and q2 + q3 + q4 the angle of x4 in frame 1's x1–y1 plane.
    """
    T = np.asarray(transform, dtype=float)
    position, x6, y6, z6 = T[:3, 3], T[:3, 0], T[:3, 1], T[:3, 2]
    wrist = position - D[5] * z6
    radius = math.hypot(wrist[0], wrist[1])
    if radius < D[3]:
        return np.empty((0, 6))  # the wrist centre is within d4 of the base axis
    psi, spread = math.atan2(wrist[1], wrist[0]), math.acos(D[3] / radius)
    solutions = []
    for q1 in (psi + math.pi / 2 + spread, psi + math.pi / 2 - spread):
        s1, c1 = math.sin(q1), math.cos(q1)
        cos5 = (position[0] * s1 - position[1] * c1 - D[3]) / D[5]
        if abs(cos5) > 1.0 + 1e-12:
            continue
        for q5 in (math.acos(min(1.0, max(-1.0, cos5))), -math.acos(min(1.0, max(-1.0, cos5)))):
            s5, c5 = math.sin(q5), math.cos(q5)
            q6 = 0.0 if abs(s5) < SINGULAR else math.atan2(-(y6[0] * s1 - y6[1] * c1) / s5,
                                                           (x6[0] * s1 - x6[1] * c1) / s5)
            s6, c6 = math.sin(q6), math.cos(q6)
            x4 = c5 * c6 * x6 - c5 * s6 * y6 - s5 * z6
            p4 = wrist + D[4] * (s6 * x6 + c6 * y6)
            px, py = p4[0] * c1 + p4[1] * s1, p4[2] - D[0]
            cos3 = (px * px + py * py - A[1] ** 2 - A[2] ** 2) / (2 * A[1] * A[2])
            if abs(cos3) > 1.0 + 1e-12:
                continue
            q234 = math.atan2(x4[2], x4[0] * c1 + x4[1] * s1)
            for q3 in (math.acos(min(1.0, max(-1.0, cos3))), -math.acos(min(1.0, max(-1.0, cos3)))):
                q2 = math.atan2(py, px) - math.atan2(A[2] * math.sin(q3), A[1] + A[2] * math.cos(q3))
                solutions.append([q1, q2, q3, q234 - q2 - q3, q5, q6])
    return wrap(np.array(solutions).reshape(-1, 6))


def wrap(angles: np.ndarray) -> np.ndarray:
    """Angles in (−π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(angles, dtype=float), 2 * np.pi)


def nearest_inverse(pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
    """The joint angles for controller pose ``pose`` closest to ``seed`` (the previous q): of all
    solutions of :func:`inverse`, the one with the least largest joint move, each joint unwrapped to
    lie within π of its seed (a UR's joints turn ±2π, so q moves continuously). None if the pose is
    out of reach."""
    solutions = inverse(pose_to_transform(pose))
    if len(solutions) == 0:
        return None
    seed = np.asarray(seed, dtype=float)
    unwrapped = seed + wrap(solutions - seed)
    return unwrapped[int(np.argmin(np.max(np.abs(unwrapped - seed), axis=1)))]
