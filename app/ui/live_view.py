"""The dashboard's live view of a handover: a 3-D scene and the coupling signals, from the loop's rows.

Scene (robot base frame, metres, z up): the arm — where the rows carry the joint angles the arm
reported, the UR5 as kinematic links through its joint positions (``links``, computed by forward
kinematics below this package: :mod:`app.session.drawing`), otherwise (the mock arm, samples stored
without them) a stand-in arm (base column and two links to the TCP) — the TCP and its path (blue), the
tracked hand and its path (red), the handover point H (green), the robot start R. Plots:
τ = τ0(1 + C_t) (eq. 5), σ_j(d̃̇) (eq. 10) and the filtered distance d̃ (eq. 7) against trial time.
"""

from __future__ import annotations

import numpy as np
import viser
import viser.uplot

from robot_io.config import SceneConfig

#: Every how many loop rows one is drawn (500 Hz → 50 points per second).
STRIDE = 10
SIGNALS: tuple[tuple[str, str, str], ...] = (("tau", "τ [s]", "#1c7ed6"),
                                             ("sigma_j", "σ_j", "#e8590c"),
                                             ("d_filtered", "d̃ [m]", "#2b8a3e"))
BASE_TOP = np.array([0.0, 0.0, 0.35])
#: Thickness of the UR5's drawn links [m] (its tubes are 0.09–0.12 m across).
UR5_THICKNESS = 0.06


def _segments(path: np.ndarray) -> np.ndarray:
    """Line segments (n−1, 2, 3) through the points of ``path`` (at least one segment)."""
    path = path[np.all(np.isfinite(path), axis=1)]
    if len(path) < 2:
        path = np.zeros((2, 3)) if len(path) == 0 else np.repeat(path, 2, axis=0)
    return np.stack([path[:-1], path[1:]], axis=1)


def elbow(tcp: np.ndarray) -> np.ndarray:
    """A plausible elbow of the stand-in arm: halfway from the shoulder to the TCP, raised."""
    return (BASE_TOP + tcp) / 2.0 + np.array([0.0, 0.0, 0.18])


class LiveView:
    """The scene and signal plots of one dashboard client."""

    def __init__(self, client: viser.ClientHandle, scene_config: SceneConfig) -> None:
        scene = client.scene
        scene.configure_environment_map(hdri=None)
        scene.set_up_direction("+z")
        scene.add_grid("/floor", width=2.0, height=2.0, cell_size=0.1, position=(0.5, 0.0, 0.0))
        start = scene_config.point("robot_start")
        goal = scene_config.point("handover_point")
        self.base = scene.add_cylinder("/arm/base", radius=0.07, height=0.35, color=(90, 90, 90),
                                       position=(0.0, 0.0, 0.175))
        scene.add_icosphere("/H", radius=0.025, color=(47, 158, 68), opacity=0.6,
                            position=tuple(goal))
        scene.add_label("/H/label", "H", position=(0.0, 0.0, 0.05))
        scene.add_label("/R", "R", position=tuple(start + np.array([0.0, 0.0, 0.05])))
        self.links = scene.add_line_segments("/arm/links", self._arm(start), colors=(70, 70, 70),
                                             thickness=0.03)
        self.ur5 = scene.add_line_segments("/arm/ur5", _segments(np.zeros((0, 3))),
                                           colors=(70, 70, 70), thickness=UR5_THICKNESS, visible=False)
        self.tcp = scene.add_icosphere("/tcp", radius=0.03, color=(28, 126, 214),
                                       position=tuple(start))
        self.tcp_path = scene.add_line_segments("/tcp_path", _segments(start[None]),
                                                colors=(28, 126, 214), thickness=0.006)
        self.hand = scene.add_icosphere("/hand", radius=0.035, color=(224, 49, 49),
                                        position=tuple(scene_config.point("hand_start")))
        self.hand_path = scene.add_line_segments("/hand_path", _segments(np.zeros((0, 3))),
                                                 colors=(224, 49, 49), thickness=0.006)
        client.camera.position = (1.45, -1.05, 0.85)
        client.camera.look_at = (0.45, 0.0, 0.2)
        client.camera.up_direction = (0.0, 0.0, 1.0)
        self.plots = {name: self._plot(client.gui, label, color) for name, label, color in SIGNALS}
        self.rows_shown = -1

    @staticmethod
    def _arm(tcp: np.ndarray) -> np.ndarray:
        joints = np.stack([BASE_TOP, elbow(tcp), tcp])
        return np.stack([joints[:-1], joints[1:]], axis=1)

    @staticmethod
    def _plot(gui: viser.GuiApi, label: str, color: str) -> viser.GuiUplotHandle:
        empty = (np.zeros(1), np.zeros(1))
        return gui.add_uplot(
            empty, (viser.uplot.Series(label="t [s]"),
                    viser.uplot.Series(label=label, stroke=color, width=2)),
            scales={"x": viser.uplot.Scale(time=False, auto=True)},
            legend=viser.uplot.Legend(show=True), aspect=3.0)

    def update(self, rows: dict[str, np.ndarray] | None) -> None:
        """Draw the rows of the running (or last) trial; nothing to do if they did not change."""
        if rows is None or len(rows["t"]) == self.rows_shown or len(rows["t"]) == 0:
            return
        self.rows_shown = len(rows["t"])
        self.draw(rows)

    def draw(self, rows: dict[str, np.ndarray]) -> None:
        """The robot and the hand where the last row has them, their paths and the signals so
        far (a live trial's rows, or a replay's, with their ``links``)."""
        measured, hand = rows["measured"], rows["hand"]
        tcp, links = measured[-1], rows["links"][-1]
        self.tcp.position = tuple(tcp)
        ur5 = bool(np.all(np.isfinite(links)))
        if ur5:
            self.ur5.points = _segments(links)
        else:
            self.links.points = self._arm(tcp)
        if ur5 != self.ur5.visible:
            self.ur5.visible, self.links.visible, self.base.visible = ur5, not ur5, not ur5
        self.tcp_path.points = _segments(measured)
        valid_hand = hand[np.all(np.isfinite(hand), axis=1)]
        if len(valid_hand):
            self.hand.position = tuple(valid_hand[-1])
        self.hand_path.points = _segments(hand)
        t = rows["t"]
        for name, plot in self.plots.items():
            values = rows[name]
            keep = np.isfinite(values)
            if keep.sum() >= 2:
                plot.data = (t[keep], values[keep])
