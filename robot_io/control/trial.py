"""Assemble one handover from the configuration: DMP from R to H, coupling θ, hand, arm, clock."""

from __future__ import annotations

from robot_io.arms.arm import Arm
from robot_io.arms.mock_arm import MockArm
from robot_io.clock import Clock, RealClock, SimClock
from robot_io.config import ControllerConfig
from robot_io.control.compliance import CompliantCoupling
from robot_io.control.coupling import Coupling, HandCoupling, NoCoupling
from robot_io.control.dmp import DMP
from robot_io.control.loop import HandoverLoop, HoldPhase, StageCallback, StopRequest, TrialRecord
from robot_io.control.recorder import TrialRecorder
from robot_io.control.safety import SafetyLimiter
from robot_io.control.stages import CycleTable
from robot_io.hands.hand import HandSource
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.theta import Theta


def make_clock(config: ControllerConfig, realtime: bool, *,
               realtime_priority: bool | None = None) -> Clock:
    """The wall clock at the loop's rate (``realtime``) or the simulated one. The wall clock raises the
    control thread's priority where the OS permits it when ``realtime_priority`` says so (a rig's
    setting, resolved at start), or, for None, unless ``[loop] realtime_priority = false``."""
    if realtime:
        wanted = (config.loop.realtime_priority is not False if realtime_priority is None
                  else realtime_priority)
        return RealClock(config.loop.rate_hz, realtime_priority=wanted)
    return SimClock(config.loop.rate_hz)


def make_coupling(config: ControllerConfig, theta: Theta | None, dt: float) -> Coupling:
    """The hand coupling of eqs. (6)–(10) with θ, or no coupling at all for ``theta=None``."""
    if theta is None:
        return NoCoupling()
    return HandCoupling(theta, config.scene.point("handover_point"), config.dmp, dt)


def make_loop(config: ControllerConfig, theta: Theta | None, hand: HandSource, arm: Arm,
              clock: Clock, *, hold: HoldPhase | None = None, on_stage: StageCallback | None = None,
              recorder: TrialRecorder | None = None, stop: StopRequest | None = None,
              cycle: CycleTable | None = None) -> HandoverLoop:
    """A handover from the robot start R to the handover point H, the arm first moved to R
    (:func:`build_loop`)."""
    arm.move_to(config.scene.point("robot_start"), stop)
    return build_loop(config, theta, hand, arm, clock, hold=hold, on_stage=on_stage,
                      recorder=recorder, stop=stop, cycle=cycle)


def build_loop(config: ControllerConfig, theta: Theta | None, hand: HandSource, arm: Arm,
               clock: Clock, *, hold: HoldPhase | None = None, on_stage: StageCallback | None = None,
               recorder: TrialRecorder | None = None, stop: StopRequest | None = None,
               cycle: CycleTable | None = None) -> HandoverLoop:
    """A handover from the robot start R to the handover point H, the arm where it is. With
    ``hold``, the robot then holds the object out at H with the k_ext compliance term of Table I
    while the participant grasps it (:class:`~robot_io.control.compliance.CompliantCoupling`)."""
    start, goal = config.scene.point("robot_start"), config.scene.point("handover_point")
    coupling = make_coupling(config, theta, clock.period)
    if hold is not None:
        release = hold.release
        coupling = CompliantCoupling(coupling, hold.read_force, config.dmp.k_ext,
                                     grasped=lambda: release.grasped,
                                     baseline=lambda: release.baseline)
    return HandoverLoop(
        dmp=DMP.from_minimum_jerk(start, goal, config.dmp),
        coupling=coupling,
        hand=hand, arm=arm, clock=clock,
        limiter=SafetyLimiter(config.safety, clock.period),
        config=config.loop, hold=hold, on_stage=on_stage, recorder=recorder, stop=stop, cycle=cycle,
    )


def simulate_trial(config: ControllerConfig, theta: Theta | None, scenario: Scenario, seed: int,
                   realtime: bool = False) -> TrialRecord:
    """One handover of the simulated hand with the mock arm, on simulated (or real) time."""
    clock = make_clock(config, realtime)
    hand = SimulatedHand(scenario, config.scene, config.hand, seed)
    arm = MockArm(clock, config.scene.point("robot_start"))
    return make_loop(config, theta, hand, arm, clock).run()
