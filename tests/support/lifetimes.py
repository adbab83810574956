"""Stress scenarios for the objects that two threads (or processes) share, run in a child process
(``python -m support.lifetimes SCENARIO CYCLES``) so that a crash of the interpreter fails its test
with the signal, instead of killing the test worker (docs/architecture.md, "Shared objects and
their lifetimes"). Each scenario opens and releases its object ``CYCLES`` times while other threads
use it, at moments drawn from a seeded generator, and prints one line per 10 % of the cycles and
``survived N cycles`` at the end. A Python exception in any thread ends the scenario with a non-zero
exit: threads re-raise through :func:`run_threads`.

- ``stream``: the rig's shared-memory sample stream, read (a trial's rows, the live view, the LSL
  feed's slices) while it is released.
- ``rig``: the application's rig client: a rig process opened, a trial run on simulated time, and
  the client closed, or the rig killed, at a random moment while a screen reads the stream and the
  reader hands on the trial's end with its rows.
- ``session``: the session runner on the mock arm (simulated time, the simulated participant and
  experimenter), with screens reading its views and live rows, ended by a participant switch, a
  shutdown or the rig's death at a random moment.
- ``serve``: ``serve``'s two servers, pages of the tablet and the dashboard opening and leaving
  (viser's client handles) while views are published, then closed as Ctrl-C closes serve.
- ``rehearsal``: the session on a rehearsal rig on the wall clock: ur_rtde's interfaces to the
  stand-in controller, the dashboard backstop, the hand on NatNet or LSL, the study's LSL outlets.
- ``outlets``: the study's LSL outlets, pushed to from the feed thread, a trial's end and the
  engine's markers, closed while the rig's stream is released.
- ``hands``: the LSL and UDP hand sources, receiving samples, closed at a random moment.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

#: The generator of every random moment (a failing cycle can be found again).
SEED = 20261128
#: Participants a session runner opens one after the other before it is shut down.
SESSIONS_PER_RUNNER = 5


def progress(cycle: int, cycles: int, what: str) -> None:
    if cycles >= 10 and (cycle + 1) % (cycles // 10) == 0:
        print(f"{what}: {cycle + 1}/{cycles} cycles", flush=True)


def run_threads(*targets: Callable[[threading.Event], None]) -> tuple[threading.Event,
                                                                     Callable[[], None]]:
    """Start one thread per target (each loops until its event is set); the event and a join that
    re-raises the first exception any of them raised."""
    stop = threading.Event()
    errors: list[BaseException] = []

    def guarded(target: Callable[[threading.Event], None]) -> None:
        try:
            target(stop)
        except BaseException as exc:  # handed to the main thread
            errors.append(exc)

    threads = [threading.Thread(target=guarded, args=(t,), daemon=True) for t in targets]
    for thread in threads:
        thread.start()

    def join() -> None:
        stop.set()
        for thread in threads:
            thread.join()
        if errors:
            raise errors[0]

    return stop, join


# -- stream ---------------------------------------------------------------------------------------
def stream(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    for cycle in range(cycles):
        _stream_cycle(rng)
        progress(cycle, cycles, "stream")
    print(f"survived {cycles} cycles", flush=True)


def _stream_cycle(rng: np.random.Generator) -> None:
    from robot_io.rig.stream import SampleStream

    samples = SampleStream(5000)
    samples._header[:3] = (5000, 1, 1)  # a finished trial's rows, all counted
    _, join = run_threads(lambda stop: _read_until(stop, samples.columns),
                          lambda stop: _read_until(stop, lambda: samples.view(3)),
                          lambda stop: _read_until(stop, lambda: samples.rows_of(1, 0)))
    time.sleep(rng.uniform(0.0, 0.005))  # a moment in the readers' loops
    samples.close(unlink=True)
    assert samples.count == 0 and len(samples.columns()["t"]) == 0, "a released stream is empty"
    join()


def _read_until(stop: threading.Event, read: Callable[[], object]) -> None:
    while not stop.is_set():
        read()


# -- rig ------------------------------------------------------------------------------------------
def rig(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    ends = {"completed": 0, "with rows": 0, "killed": 0}
    for cycle in range(cycles):
        _rig_cycle(rng, cycle, ends)
        progress(cycle, cycles, "rig")
    print(f"trial ends: {json.dumps(ends)}", flush=True)
    print(f"survived {cycles} cycles", flush=True)


def _rig_cycle(rng: np.random.Generator, cycle: int, ends: dict[str, int]) -> None:
    """A rig opened, up to three trials run, then the client closed (after the rig was killed, one
    time in four) at a random moment; the reader reads each trial's rows as a supervisor does, and
    a screen reads the stream and asks whether the rig is alive (its process handle, which the
    client releases once the rig is joined)."""
    from robot_io.config import ControllerConfig
    from robot_io.hands.simulated_hand import Scenario
    from robot_io.rig.client import RigClient
    from robot_io.rig.messages import RigSpec, RunTrial, TrialDone
    from robot_io.theta import Theta

    done = threading.Event()

    def listen(client: RigClient, report: object) -> None:
        if isinstance(report, TrialDone):
            rows = len(client.stream.columns()["t"])
            assert rows == report.rows, f"{rows} rows handed on of the {report.rows} written"
            ends["completed"] += report.summary.outcome == "completed"
            ends["with rows"] += rows > 0
            done.set()

    client = RigClient(RigSpec(config=ControllerConfig(), scenario=Scenario.STRAIGHTFORWARD,
                               realtime=False, realtime_priority=False), listen)
    _, join = run_threads(lambda stop: _read_until(stop, lambda: (client.stream.view(4),
                                                                   client.alive, client.pid)))
    try:
        for index in range(1, 4):
            done.clear()
            client.run_trial(RunTrial(trial_index=index, theta=Theta(a=5.0, delta=-0.2, k=5.0),
                                      hand_seed=cycle, automatic=True))
            if rng.random() < 0.3:  # ended at a random moment of this trial
                break
            done.wait(60)
        time.sleep(rng.uniform(0.0, 0.3))
        if rng.random() < 0.25:
            client.kill()  # the rig dies; its end is reported, then the client is closed
            ends["killed"] += 1
    finally:
        client.close()
        join()
    assert client.reports_handed_on(), "the reader handed on every report"
    assert client.stream.released, "the stream is released once its reader and close are done"
    assert client.pid is None and client.exit_code is not None, "the process handle is released"


# -- session --------------------------------------------------------------------------------------
def session(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    # each runner serves a few participants: every session but its last ends by a switch (after
    # its rig's death, one time in two), its last by the shutdown
    ends = {"switch": 0, "rig death, then switch": 0, "shutdown": 0}
    with tempfile.TemporaryDirectory(prefix="lifetimes-") as folder:
        study, cycle = Path(folder) / "study", 0
        while cycle < cycles:
            cycle = _runner_cycles(rng, study, cycle, cycles, ends)
    print(f"ends: {json.dumps(ends)}", flush=True)
    print(f"survived {cycles} cycles", flush=True)


def _runner_cycles(rng: np.random.Generator, study: Path, cycle: int, cycles: int,
                   ends: dict[str, int]) -> int:
    """One runner's sessions, from cycle ``cycle`` on; the next cycle."""
    from app.protocol.errors import RefusedAction
    from app.session.config import LabConfig
    from app.session.runner import SessionRunner
    from robot_io.hands.simulated_hand import Scenario
    from support.engine import BRIEF_PROTOCOL

    lab = LabConfig.model_validate({"protocol": BRIEF_PROTOCOL})
    runner = SessionRunner(study, lab, realtime=False, auto_experimenter=True)
    _, join = run_threads(lambda stop: _read_until(stop, lambda: runner.live(4)),
                          lambda stop: _read_until(stop, lambda: runner.view.trials))
    try:
        runner.set_auto(True)
        for turn in range(SESSIONS_PER_RUNNER):
            runner.open(f"P{cycle:04d}", Scenario.PERTURBED, seed=cycle + 1)
            time.sleep(rng.uniform(0.0, 0.6))  # trials start, run and end meanwhile
            cycle += 1
            progress(cycle - 1, cycles, "session")
            if turn == SESSIONS_PER_RUNNER - 1 or cycle >= cycles:
                ends["shutdown"] += 1
                break
            if turn % 2 and (client := runner.rig) is not None:
                client.kill()
                time.sleep(rng.uniform(0.0, 0.3))  # its death is handed on meanwhile
                ends["rig death, then switch"] += 1
            else:
                ends["switch"] += 1
            _end_session(runner, RefusedAction)
    finally:
        runner.close()
        join()
    return cycle


def _end_session(runner, refused: type[Exception]) -> None:
    """End the open session, aborting a running trial first (End session is refused meanwhile)."""
    for _ in range(200):
        try:
            runner.end_session()
            return
        except refused:
            with contextlib.suppress(refused):
                runner.abort_trial()
            time.sleep(0.01)  # the abort is handed on meanwhile
    raise AssertionError(f"the session did not end: {runner.view.step}, {runner.view.stage}")


# -- outlets --------------------------------------------------------------------------------------
def outlets(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    for cycle in range(cycles):
        _outlets_cycle(rng, cycle)
        progress(cycle, cycles, "outlets")
    print(f"survived {cycles} cycles", flush=True)


def _outlets_cycle(rng: np.random.Generator, cycle: int) -> None:
    """The rig's stream written, the feed and a trial's end pushing it, then the stream released
    (as when the rig dies) and the outlets closed."""
    from app.session.config import RecordSettings
    from app.session.lsl_outlets import StudyOutlets
    from robot_io.rig.stream import SampleStream

    settings = RecordSettings(lsl_outlets=True, lsl_name=f"lifetimes-{os.getpid()}")
    samples = SampleStream(2000)
    rig_side = SampleStream(2000, name=samples.name)  # the rig's own mapping of the block
    rig_side._header[:3] = (0, 1, 0)
    opened = StudyOutlets(settings, "P01", f"2026-11-28T00:00:{cycle % 60:02d}", 500,
                          lambda: samples)
    opened.feed.go(1, time.monotonic())

    def write(stop: threading.Event) -> None:  # the rig's rows, counted as they come
        count = 0
        while not stop.is_set() and count < 1999:
            count += 1
            rig_side._rows[count - 1, 0] = count / 500
            rig_side._header[0] = count

    _, join = run_threads(write, lambda stop: _read_until(stop, opened.feed.flush))
    time.sleep(rng.uniform(0.0, 0.02))
    samples.close(unlink=True)  # the application's mapping goes, as when its rig is closed
    opened.close()
    join()
    rig_side.close()


# -- serve ----------------------------------------------------------------------------------------
def serve(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    with tempfile.TemporaryDirectory(prefix="lifetimes-") as folder:
        for cycle in range(cycles):
            _serve_cycle(rng, Path(folder) / "study", cycle)
            progress(cycle, cycles, "serve")
    print(f"survived {cycles} cycles", flush=True)


def _serve_cycle(rng: np.random.Generator, study: Path, cycle: int) -> None:
    """``serve``'s servers over a session on simulated time, pages of both screens coming and going
    (viser's websocket, as a browser opens it) while views are published and the live view ticks;
    then the servers closed, as Ctrl-C closes serve."""
    import viser
    from websockets.exceptions import ConnectionClosed, InvalidStatus
    from websockets.sync.client import connect

    from app.session.config import LabConfig
    from app.session.runner import SessionRunner
    from app.ui.server import HandoverServers, ServeOptions
    from robot_io.hands.simulated_hand import Scenario
    from support.engine import BRIEF_PROTOCOL

    runner = SessionRunner(study, LabConfig.model_validate({"protocol": BRIEF_PROTOCOL}),
                           realtime=False, auto_experimenter=True)
    try:
        servers = HandoverServers(runner, ServeOptions(tablet_port=0, dashboard_port=0,
                                                       token="stress-token"))
    except BaseException:
        runner.close()
        raise
    ports = [servers.tablet_server.get_port(), servers.dashboard_server.get_port()]

    def pages(stop: threading.Event) -> None:
        while not stop.is_set():
            port = ports[int(rng.integers(2))]
            try:
                with connect(f"ws://127.0.0.1:{port}", origin=f"http://127.0.0.1:{port}",
                             subprotocols=[f"viser-v{viser.__version__}"]):
                    time.sleep(rng.uniform(0.0, 0.2))  # the page is open meanwhile
            except (OSError, ConnectionClosed, InvalidStatus):  # the servers closed under the page
                time.sleep(0.01)

    _, join = run_threads(pages, pages)
    try:
        runner.set_auto(True)
        runner.open(f"S{cycle:04d}", Scenario.PERTURBED, seed=cycle + 1)
        time.sleep(rng.uniform(0.2, 1.0))
    finally:
        servers.close()
        join()


# -- rehearsal ------------------------------------------------------------------------------------
def rehearsal(cycles: int) -> None:
    rng = np.random.default_rng(SEED)
    ends = {"switch": 0, "rig death, then switch": 0, "shutdown": 0}
    with tempfile.TemporaryDirectory(prefix="lifetimes-") as folder:
        study, cycle = Path(folder) / "study", 0
        while cycle < cycles:
            cycle = _rehearsal_cycles(rng, study, cycle, cycles, ends)
    print(f"ends: {json.dumps(ends)}", flush=True)
    print(f"survived {cycles} cycles", flush=True)


def _rehearsal_cycles(rng: np.random.Generator, study: Path, cycle: int, cycles: int,
                      ends: dict[str, int]) -> int:
    """A rehearsal rig on the wall clock (the stand-in UR over RTDE with the dashboard backstop, the
    hand on NatNet or LSL, the study's LSL outlets), its sessions ended as in :func:`session`."""
    from app.protocol.errors import RefusedAction
    from app.session.config import LabConfig
    from app.session.rehearsal import Rehearsal
    from app.session.runner import SessionRunner
    from robot_io.hands.simulated_hand import Scenario
    from support.engine import BRIEF_PROTOCOL

    lab = LabConfig.model_validate({"protocol": BRIEF_PROTOCOL,
                                    "record": {"lsl_name": f"lifetimes-{os.getpid()}"}})
    rig = Rehearsal(lab, hand="natnet" if cycle % 2 else "lsl")
    try:
        runner = SessionRunner(study, lab, rehearsal=rig, auto_experimenter=True,
                               realtime_priority=True)
    except BaseException:
        rig.close()
        raise
    _, join = run_threads(lambda stop: _read_until(stop, lambda: runner.live(4)))
    try:
        runner.set_auto(True)
        for turn in range(SESSIONS_PER_RUNNER):
            runner.open(f"R{cycle:04d}", Scenario.PERTURBED, seed=cycle + 1)
            time.sleep(rng.uniform(0.0, 4.0))  # a trial prepares, reaches, is handed over meanwhile
            cycle += 1
            progress(cycle - 1, cycles, "rehearsal")
            if turn == SESSIONS_PER_RUNNER - 1 or cycle >= cycles:
                ends["shutdown"] += 1
                break
            if turn % 2 and (client := runner.rig) is not None:
                client.kill()
                time.sleep(rng.uniform(0.0, 0.3))
                ends["rig death, then switch"] += 1
            else:
                ends["switch"] += 1
            _end_session(runner, RefusedAction)
    finally:
        runner.close()
        join()
    return cycle


# -- hands ----------------------------------------------------------------------------------------
def hands(cycles: int) -> None:
    import pylsl

    from robot_io.config import ControllerConfig
    from robot_io.devices import tracker_transform
    from robot_io.hands.lsl_hand import LSLHand
    from robot_io.hands.udp_hand import UDPHand

    rng = np.random.default_rng(SEED)
    name = f"lifetimes-hand-{os.getpid()}"
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, "Mocap", 3, 200, pylsl.cf_double64,
                                                 f"{name}-source"))
    config = ControllerConfig()
    lsl = config.hand_source.as_kind("lsl", lsl_stream_name=name, lsl_stream_type="Mocap")
    # port 0: the kernel's free port, which no lab configures (so only a copy takes it)
    udp = config.hand_source.as_kind("udp", udp_host="127.0.0.1").model_copy(update={"udp_port": 0})
    transform, sender = tracker_transform(config), socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def publish(stop: threading.Event) -> None:
        while not stop.is_set():
            outlet.push_sample([0.1, 0.2, 0.3])
            time.sleep(0.005)

    _, join_publisher = run_threads(publish)
    try:
        for cycle in range(cycles):
            if cycle % 2 == 0:
                hand: LSLHand | UDPHand = LSLHand(lsl, transform, config.hand.max_speed)
            else:
                hand = UDPHand(udp, transform, config.hand.max_speed)
                for _ in range(20):
                    sender.sendto(b'{"x": 0.1, "y": 0.2, "z": 0.3}', hand.address)
            time.sleep(rng.uniform(0.0, 0.05))
            hand.close()
            progress(cycle, cycles, "hands")
    finally:
        join_publisher()
        sender.close()
    print(f"survived {cycles} cycles", flush=True)


SCENARIOS = {"stream": stream, "rig": rig, "session": session, "serve": serve, "rehearsal": rehearsal,
             "outlets": outlets, "hands": hands}
#: Set by ``make soak`` (.ci/soak.py): the cycles of every scenario (the suite runs a few).
CYCLES_VARIABLE = "HANDOVER_STRESS_CYCLES"
#: The ceiling of one scenario of many cycles (``make soak``; its run passes --timeout=0): the
#: rehearsal's 500 cycles take about 20 CPU-s each.
SOAK_CEILING_S = 6 * 3600.0


def stress_marks() -> list[pytest.MarkDecorator]:
    """The marks of a stress test module: ``stress``, and for ``make soak``'s many cycles a ceiling
    above the suite's (a test not marked slow has 300 s, tests/conftest.py)."""
    marks = [pytest.mark.stress]
    if os.environ.get(CYCLES_VARIABLE):
        marks.append(pytest.mark.timeout(SOAK_CEILING_S))
    return marks


def survive(scenario: str, cycles: int, ceiling_s: float = SOAK_CEILING_S) -> str:
    """Run ``scenario`` for ``cycles`` cycles (``$HANDOVER_STRESS_CYCLES`` instead, when set) in a
    child process; its output. Fails with the child's exit (a signal: the interpreter crashed) and
    the end of its output when it does not end well; ``ceiling_s`` is a ceiling for a hung child."""
    import subprocess

    cycles = int(os.environ.get(CYCLES_VARIABLE, cycles))
    tests = Path(__file__).resolve().parents[1]
    # the project before tests/ (whose robot_io folder of tests is no package)
    path = os.pathsep.join([str(tests.parent), str(tests), os.environ.get("PYTHONPATH", "")])
    try:
        done = subprocess.run([sys.executable, "-X", "faulthandler", "-m", "support.lifetimes",
                               scenario, str(cycles)], cwd=tests, capture_output=True, text=True,
                              timeout=ceiling_s, env={**os.environ, "PYTHONPATH": path})
    except subprocess.TimeoutExpired as hung:
        raise AssertionError(f"the {scenario} scenario did not end within {ceiling_s:g} s; its "
                             f"output: {hung.stdout!r} {hung.stderr!r}") from hung
    output = done.stdout + done.stderr
    how = (f"killed by signal {-done.returncode}" if done.returncode < 0
           else f"exit code {done.returncode}")
    assert done.returncode == 0 and f"survived {cycles} cycles" in done.stdout, (
        f"the {scenario} scenario ended with {how}:\n{output[-6000:]}")
    assert "Traceback" not in output, f"the {scenario} scenario printed a traceback:\n{output[-6000:]}"
    return output

if __name__ == "__main__":
    SCENARIOS[sys.argv[1]](int(sys.argv[2]))
    sys.stdout.flush()
