"""What the dashboard's 3-D view is given to draw, computed here so that ``app/ui`` only renders.

A trial's rows (live from the rig's stream, or stored) gain ``links``: for each row the origins of the
UR5's base frame and joint frames 1 … 6, (n, 7, 3), by forward kinematics
(:func:`robot_io.arms.ur_kinematics.link_points`) of the joint angles ``q`` the arm reported. Rows without
joint angles (the mock arm, samples stored before schema version 4) give NaN links, and the view
draws the tool point alone there.
"""

from __future__ import annotations

import numpy as np

from robot_io.arms.ur_kinematics import link_points


def with_links(rows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``rows`` and their ``links`` (n, 7, 3): the UR5's joint positions from ``q`` (n, 6)."""
    return {**rows, "links": link_points(rows["q"])}
