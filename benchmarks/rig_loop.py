"""500 Hz deadline misses of the handover cycle in the rig process against the same cycle in a thread
of the application's process (how the web app ran trials before the rig process), in one run.

    python benchmarks/rig_loop.py [--trials 4]

Rehearsal rig with an e-Series stand-in (500 Hz): ur_rtde against the stand-in controller, the
simulated hand on LSL, the tool-output gripper and the force release. During every trial both screens
are open in headless Chromium (the dashboard unlocked, its live view streaming) and a second learner
process fits continuously. Four variants, each with the normal scheduling policy (the baseline) and
with real-time priority (SCHED_FIFO): rig process, in-process thread. Prints per variant: deadline
misses (share of cycles, goal < 0.1 % with priority), cycle lateness p50/p99, and the time from Go
to the first servoL target the controller received — from the click on the dashboard's Go button
for the rig process (the whole path: browser, websocket, runner, pipe, rig), from the cycle's Go
stage for the thread. The stand-in controller and the hand publisher run under SCHED_FIFO in every
variant (they stand for hardware of their own). The machine is shared: read the figures against the
load printed with them.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))
sys.path.insert(0, str(Path(__file__).parent))

from support.browser import (
    TOKEN,
    chromium,
    open_page,
    pair_tablet,
    tap_point,
    unlock_dashboard,
)
from ui_latency import busy_learner

from app.session.config import LabConfig
from app.session.rehearsal import Rehearsal
from app.session.runner import SessionRunner
from app.ui.server import HandoverServers, ServeOptions
from robot_io.control.cycle import Gates, run_cycle
from robot_io.control.loop import Outcome
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import RigSpec
from robot_io.standins.ur.control_script import SERVOL
from robot_io.theta import Theta

PROTOCOL = {"initial_trials": 5, "batch_size": 5, "learning_batches": 1, "best_trials": 1,
            "validation_batches": 1}


def first_servo_after(rehearsal: Rehearsal, since: float) -> float | None:
    """When the stand-in received its first servoL target after ``since`` (time.monotonic)."""
    times = [t for t, command, _ in rehearsal.control("received")["received"]
             if command == SERVOL and t > since]
    return min(times) if times else None


def wait(condition, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError("benchmark step timed out")
        time.sleep(0.005)


class Figures:
    def __init__(self) -> None:
        self.misses = self.cycles = self.faults = 0
        self.lateness: list[float] = []
        self.go_to_servo: list[float] = []
        self.click_to_go: list[float] = []

    def add(self, misses: int, samples: dict[str, np.ndarray], go_to_servo: float | None) -> None:
        self.misses += misses
        self.cycles += len(samples["t"])
        self.lateness.extend(samples["lateness_s"][np.isfinite(samples["lateness_s"])].tolist())
        if go_to_servo is not None:
            self.go_to_servo.append(go_to_servo)

    def line(self, label: str) -> str:
        late = np.asarray(self.lateness) * 1e3
        go = sorted(1e3 * x for x in self.go_to_servo)
        return (f"{label:38s} misses {self.misses:4d} of {self.cycles:6d} = "
                f"{100 * self.misses / max(self.cycles, 1):6.3f} %   lateness p50 "
                f"{np.percentile(late, 50):.3f} ms, p99 {np.percentile(late, 99):.3f} ms   "
                + (f"Go → first servoL median {statistics.median(go):.1f} ms (max {go[-1]:.1f})"
                 if go else "Go → first servoL: no trial reached Go")
                + (f" (click → rig's Go stage {1e3 * statistics.median(self.click_to_go):.1f} ms)"
                   if self.click_to_go else "")
                + (f"   trials aborted by a fault: {self.faults}" if self.faults else ""))


def show(figures: Figures, label: str) -> None:
    print(f"{figures.line(label)}   (load average {os.getloadavg()[0]:.1f})", flush=True)


def both_variants(study: Path, browser, priority: bool, trials: int) -> None:
    """Both screens open on a session runner; first its rig process runs trials driven from the
    dashboard page, then, with the screens still open, the in-process thread runs as many."""
    lab = LabConfig.model_validate({"protocol": PROTOCOL})
    runner = SessionRunner(study, lab, rehearsal=Rehearsal(lab, series="e"),
                           realtime_priority=priority)
    servers = HandoverServers(runner, ServeOptions(tablet_port=0, dashboard_port=0,
                                                   token=TOKEN))
    try:
        tablet_url, dashboard_url = servers.urls()
        tablet = open_page(browser, tablet_url, touch=True)
        dashboard = open_page(browser, dashboard_url, size=(1400, 900))
        unlock_dashboard(dashboard)
        pair_tablet(dashboard, tablet)  # Start needs exactly one paired tablet
        runner.open(f"B{int(priority)}", Scenario.PERTURBED, seed=1)
        policy = "SCHED_FIFO" if priority else "normal policy"
        # each figure is printed as measured, so a later variant that fails does not lose it
        show(rig_process(runner, dashboard, trials), f"rig process, {policy}")
        show(in_process_thread(priority, trials), f"in-process thread, {policy}")
    finally:
        servers.close()


def rig_process(runner: SessionRunner, dashboard, trials: int) -> Figures:
    """Trials run by the session runner's rig process, Go clicked on the dashboard page."""
    figures = Figures()
    go_stage: list[float] = []
    play = runner.rehearsal.play

    def played(scenario: Scenario, seed: int, go_monotonic: float) -> None:
        go_stage.append(go_monotonic)  # the rig's Go stage, on its clock (time.monotonic)
        play(scenario, seed, go_monotonic)

    runner.rehearsal.play = played
    for n in range(1, trials + 1):
        wait(lambda: runner.view.step is not None and runner.view.step.value == "ready")
        runner.start_trial()
        wait(lambda: runner.view.waiting_for == Stage.PREPARE)
        runner.confirm(Stage.PREPARE)  # Object loaded
        wait(lambda: runner.view.waiting_for == Stage.READY)
        index = runner.view.trials[-1].trial_index
        point = tap_point(dashboard, "Go")  # once the dashboard shows it enabled
        before = len(go_stage)
        clicked = time.monotonic()
        dashboard.mouse.click(*point)
        wait(lambda: runner.view.trials[-1].outcome is not None)
        wait(lambda before=before: len(go_stage) > before)  # the runner has seen this Go
        trial = runner.view.trials[-1]
        assert trial.trial_index == index
        servo = first_servo_after(runner.rehearsal, clicked)
        figures.add(trial.deadline_misses, runner.rig.stream.columns(),
                    None if servo is None else servo - clicked)
        figures.click_to_go.append(go_stage[-1] - clicked)
        if trial.outcome.value != "completed":  # e.g. the controller's watchdog under load
            figures.faults += 1
            if runner.view.arm_fault is not None:
                runner.recover_arm()
            continue
        wait(lambda: runner.view.step.value == "place")
        runner.place(trial.interaction, position=n / (trials + 1))
    return figures


def thread_trial(devices: RigDevices, rehearsal: Rehearsal, seed: int
                 ) -> tuple[int, dict[str, np.ndarray], float | None, bool]:
    """One cycle in a thread of this process; the hand publisher plays from its Go. Also
    whether it completed (a fault, e.g. the controller's watchdog under load, ends it early;
    the arm is then recovered)."""
    go: dict[str, float] = {}
    result: dict = {}

    def on_stage(stage: Stage, t: float) -> None:
        if stage == Stage.GO:
            go["at"] = time.monotonic()
            rehearsal.play(Scenario.PERTURBED, seed, go["at"])

    def cycle() -> None:
        result["record"] = run_cycle(devices.config, Theta(a=5.0, delta=-0.2, k=5.0),
                                     devices.for_trial(seed), Gates.automatic(), on_stage)

    thread = threading.Thread(target=cycle, name="handover-loop")
    thread.start()
    thread.join()
    rehearsal.rest()
    record = result["record"]
    servo = first_servo_after(rehearsal, go["at"]) if "at" in go else None
    completed = record.summary.outcome is Outcome.COMPLETED
    if not completed:
        devices.recover(inspected=True)
    return (record.summary.deadline_misses, record.samples,
            None if servo is None else servo - go["at"], completed)


def in_process_thread(priority: bool, trials: int) -> Figures:
    """The same cycle on the same devices in a thread of this process (beside the servers)."""
    lab = LabConfig.model_validate({"protocol": PROTOCOL})
    rehearsal = Rehearsal(lab, series="e")
    spec = RigSpec(config=rehearsal.lab.controller, scenario=Scenario.PERTURBED, realtime=True,
                   realtime_priority=priority)
    devices = RigDevices(spec)
    figures = Figures()
    try:
        for n in range(trials):
            misses, samples, go_to_servo, completed = thread_trial(devices, rehearsal, seed=n)
            figures.add(misses, samples, go_to_servo)
            figures.faults += not completed
            time.sleep(0.5)
    finally:
        devices.close()
        rehearsal.close()
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=4, help="trials per variant")
    args = parser.parse_args()
    stop = threading.Event()
    learner = threading.Thread(target=busy_learner, args=(stop,), daemon=True)
    learner.start()
    with tempfile.TemporaryDirectory() as tmp, chromium() as browser:
        for priority in (False, True):
            both_variants(Path(tmp) / f"s{priority}", browser, priority, args.trials)
    stop.set()


if __name__ == "__main__":
    main()
