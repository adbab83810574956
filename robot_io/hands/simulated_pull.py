"""The simulated participant's pull on the object at the handover point (docs/controller.md).

Once the hand has reached the object held out by the robot (within ``reach_m`` of the TCP, the TCP
still) and the gripper still holds it, the participant grasps for ``grasp_delay_s`` and then pulls
towards where their hand came from, the force ramping linearly to ``pull_n`` over ``ramp_s``:

    F(t) = pull_n · clip((t − t_contact − grasp_delay_s) / ramp_s, 0, 1) · u,   u = (A − H)/‖A − H‖

The force vanishes the moment the gripper opens or the hand leaves. The same model drives the mock
arm's force reading and the stand-in UR controller's ``actual_TCP_force`` in rehearsals, so the
force-threshold release (:mod:`robot_io.control.release`) is exercised on both paths. ``pull_n = 0`` is a
participant who never takes the object (the trial ends ``not_taken``).
"""

from __future__ import annotations

import numpy as np

from robot_io.vector import all_finite, norm

#: The participant takes hold of the object once the TCP is slower than this [m/s].
STILL_MPS = 0.02


class SimulatedPull:
    def __init__(self, direction: np.ndarray, pull_n: float, grasp_delay_s: float,
                 ramp_s: float = 0.2, reach_m: float = 0.05) -> None:
        direction = np.asarray(direction, dtype=float)
        length = norm(direction)
        self.direction = direction / length if length > 0 else np.zeros(3)
        self.pull_n, self.grasp_delay_s, self.ramp_s, self.reach_m = pull_n, grasp_delay_s, ramp_s, reach_m
        self.contact_at: float | None = None

    def force(self, t: float, hand: np.ndarray | None, tcp: np.ndarray, holding: bool,
              tcp_speed: float = 0.0) -> np.ndarray:
        """The force [N] on the TCP at time ``t`` [s] (any monotonic time base). The participant
        takes hold once the object is held out still (TCP slower than ``STILL_MPS``), and keeps
        hold while the arm yields to the pull."""
        hand = None if hand is None else np.asarray(hand, dtype=float)
        touching = (holding and hand is not None and all_finite(hand)
                    and norm(hand - tcp) <= self.reach_m)
        if not touching:
            self.contact_at = None
            return np.zeros(3)
        if self.contact_at is None:
            if tcp_speed > STILL_MPS:
                return np.zeros(3)  # the object is still coming: wait until it is held out
            self.contact_at = t
        ramp = (t - self.contact_at - self.grasp_delay_s) / self.ramp_s
        return self.pull_n * float(np.clip(ramp, 0.0, 1.0)) * self.direction
