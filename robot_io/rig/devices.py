"""The rig's devices, opened once per rig process from the configuration, and the per-trial set the
cycle runs on (docs/controller.md, the rig process).

Each device is opened by its kind's model (:mod:`robot_io.kinds`). ``[arm] kind``
(:data:`robot_io.arms.kinds.ARMS`): a simulated arm (``mock``, the kinematic
:class:`~robot_io.arms.mock_arm.MockArm`) is made anew each trial on the trial's clock, its force the
simulated participant's pull; a real one (``ur``, :class:`~robot_io.arms.ur_arm.URArm` over ur_rtde) is
connected once. ``[hand_source] kind`` (:data:`robot_io.hands.config.HAND_SOURCES`): ``simulated`` (a
seeded :class:`~robot_io.hands.simulated_hand.SimulatedHand` per trial) or a tracker's (opened once, by
the reader its kind names). ``[gripper] kind`` (:data:`robot_io.grippers.kinds.GRIPPERS`):
``tool_output`` (the arm controller's tool digital output), ``robotiq_socket`` (a Robotiq 2F-85 on its
URCap's socket) or ``none``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from robot_io.arms.arm import ArmState, ConnectedArm, RecoverableArm
from robot_io.control.cycle import CycleDevices
from robot_io.control.trial import make_clock
from robot_io.devices import open_gripper, open_tracked_hand
from robot_io.errors import ArmFault, ConfigError, GripperFault
from robot_io.grippers.gripper import Gripper, NoGripper, ToolOutputGripper
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.hands.simulated_pull import SimulatedPull
from robot_io.hands.tracked_hand import TrackedHand
from robot_io.rig.messages import DeviceReport, RigSpec

log = logging.getLogger(__name__)

#: A device whose close takes longer is named in the log [s].
SLOW_CLOSE_S = 1.0


def check_spec(spec: RigSpec) -> None:
    """Refuse combinations that cannot work, before anything is opened."""
    config = spec.config  # its device tables are whole (ControllerConfig._devices_complete)
    if config.hand_source.simulated and spec.scenario is None:
        raise ConfigError(f"hand_source.kind = {config.hand_source.kind!r} needs the session's scenario")
    if not spec.realtime and not (config.arm.simulated and config.hand_source.simulated):
        raise ConfigError(f"simulated time needs a simulated arm and hand source (arm.kind = "
                          f"{config.arm.kind!r}, hand_source.kind = {config.hand_source.kind!r}): "
                          "real devices run on the wall clock")
    if not spec.realtime and not config.gripper.simulated:
        raise ConfigError(f"simulated time needs gripper.kind = 'none', not {config.gripper.kind!r}: "
                          "a real gripper runs on the wall clock")


class RigDevices:
    """Everything the rig process owns; :meth:`close` releases it all."""

    def __init__(self, spec: RigSpec) -> None:
        check_spec(spec)
        self.spec = spec
        config = spec.config
        self.connected: ConnectedArm | None = None  # a real arm, connected once
        self.tracked: TrackedHand | None = None
        self.gripper: Gripper = NoGripper()
        self._simulated_at = config.scene.point("robot_start")
        self._simulated: RecoverableArm | None = None  # a simulated arm, made anew each trial
        try:
            if not config.arm.simulated:
                self.connected = config.arm.connect(config)
            if config.hand_source.reader is not None:
                self.tracked = open_tracked_hand(config)
            self.gripper = open_gripper(config)
        except BaseException:
            self.close()
            raise
        rate = self.connected.rate_hz if self.connected is not None else config.loop.rate_hz
        self.config = config.model_copy(update={"loop": config.loop.model_copy(
            update={"rate_hz": rate})})

    @property
    def _scenario(self) -> Scenario:
        """The simulated hand's scenario: the rig refuses a simulated hand without one (above)."""
        assert self.spec.scenario is not None, "a simulated hand source has the session's scenario"
        return self.spec.scenario

    def report(self) -> DeviceReport:
        config, arm, tracked = self.config, self.connected, self.tracked
        source = config.hand_source
        hand_detail = (f"{tracked.PROTOCOL} {tracked.describe()}" if tracked is not None
                       else f"simulated hand ({self._scenario.value})")
        gripper_detail = config.gripper.describe(config.controller_host)
        return DeviceReport(arm=config.arm.kind, arm_detail=config.arm.describe(arm, config.loop.rate_hz),
                            polyscope_version=None if arm is None else arm.version,
                            rate_hz=config.loop.rate_hz, hand_source=source.kind,
                            hand_detail=hand_detail, gripper=config.gripper.kind,
                            gripper_detail=gripper_detail)

    def for_trial(self, hand_seed: int) -> CycleDevices:
        """The arm, hand, gripper and a fresh clock for one trial."""
        config, spec = self.config, self.spec
        clock = make_clock(config, realtime=spec.realtime, realtime_priority=spec.realtime_priority)
        hand = self.tracked or SimulatedHand(self._scenario, config.scene, config.hand, hand_seed)
        arm: RecoverableArm | None = self.connected
        if arm is None:
            if self._simulated is not None:
                self._simulated_at = self._simulated.read_pose()
            pull = SimulatedPull(config.scene.point("hand_start") - config.scene.point("handover_point"),
                                 config.hand.pull_n, config.hand.grasp_delay_s)
            gripper = self.gripper

            def force(tcp: np.ndarray, speed: float) -> np.ndarray:
                now = clock.now()
                sample = hand.latest(now)
                return pull.force(now, None if sample is None else sample.position, tcp,
                                  gripper.holding, speed)

            arm = self._simulated = config.arm.trial_arm(clock, self._simulated_at, force)
        return CycleDevices(arm=arm, hand=hand, gripper=self.gripper, clock=clock)

    def recover(self, inspected: bool) -> str:
        """Clear the arm's fault and the gripper's; moves no joint. A safety stop (protective or
        emergency) is cleared only once someone inspected its cause; a refusal touches nothing.
        Returns what was done; raises ArmFault or GripperFault if refused."""
        arm = self.connected or self._simulated
        faulted = arm if arm is not None and arm.state is ArmState.FAULT else None
        fault = None if faulted is None else faulted.fault
        if faulted is not None and faulted.safety_stopped and not inspected:
            raise ArmFault(f"not recovered: {fault} — inspect the cause, then recover from the "
                           "dashboard")
        gripper = self._recover_gripper()
        if faulted is None:
            return gripper or "the arm has no fault"
        restored = 0 if self.connected is None else self.connected.links_restored
        faulted.recover()
        # A tool-output gripper's link is the arm's RTDE server's: it dropped when the arm's did, and
        # only then is it connected again (a live link reconnected raced the server's release of
        # its registers: "One of the RTDE input registers are already in use")
        if isinstance(self.gripper, ToolOutputGripper) and self.connected is not None \
                and self.connected.links_restored > restored:
            self.gripper.reconnect()
            gripper = gripper or "the gripper's RTDE IO link connected again"
        return f"recovered from: {fault}" + (f"; {gripper}" if gripper else "")

    def _recover_gripper(self) -> str | None:
        """A gripper with a fault is connected again: a Robotiq's fault stays with its connection,
        whose state is unknown after it (one that lost its activation is activated again, which
        opens and closes its fingers once). None: it had no fault. Raises the GripperFault of the
        new connection if its cause remains (the URCap still silent)."""
        try:
            self.gripper.check()
        except GripperFault as fault:
            self.gripper.disconnect()
            self.gripper = open_gripper(self.spec.config)
            return f"gripper connected again after: {fault}"
        return None

    def stop_arm(self) -> None:
        """Stop the arm between trials (never raises)."""
        arm = self.connected or self._simulated
        if arm is not None:
            arm.stop()

    def close(self) -> None:
        """Stop the arm, then release everything (never raises)."""
        for name, action in (("arm", self.stop_arm),
                             ("gripper", lambda: self.gripper.disconnect()),
                             ("hand source", lambda: _close(self.tracked)),
                             ("arm's connection", lambda: _close(self.connected))):
            began = time.monotonic()
            try:
                action()
            except Exception:
                log.exception("closing the rig's %s failed", name)
            if (took := time.monotonic() - began) > SLOW_CLOSE_S:
                # the application kills a rig that is slow to exit after Shutdown: say where
                # the time went
                log.warning("closing the rig's %s took %.1f s", name, took)


def _close(device: TrackedHand | ConnectedArm | None) -> None:
    if device is not None:
        device.close()
