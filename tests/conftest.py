from __future__ import annotations

import os
from pathlib import Path

# Each test process computes on one thread: the suite runs three xdist workers on two cores, and
# the thread pools of torch (OpenMP) and numpy (OpenBLAS) spin while they wait. On two threads a
# learning test took 1.75 times the CPU of one thread for the same work, and no less wall time
# (test_posterior_slices alone, idle machine: 32.5 CPU-s in 21.0 s against 18.5 in 18.4). Set
# before numpy or torch is imported, which read it then; the processes that tests start inherit it.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from robot_io.config import ControllerConfig

#: With HANDOVER_TEST_CPU=1, the CPU time of each test (with the processes it started), the most
#: CPU-hungry listed at the end of the run; a watchdog ends a run that hangs, with every stack; the
#: tests that took over 20 s without a docstring saying why are named at the end.
pytest_plugins = ["support.cpu", "support.watchdog", "support.slow_tests"]


@pytest.fixture
def config() -> ControllerConfig:
    return ControllerConfig()


@pytest.fixture
def start(config: ControllerConfig) -> np.ndarray:
    return config.scene.point("robot_start")


@pytest.fixture
def goal(config: ControllerConfig) -> np.ndarray:
    return config.scene.point("handover_point")


# Hypothesis in CI: derandomized (a fixed seed derived from each test, so every run tries the same
# examples), no example database, no deadline (the engine's steps fit the learner); each test sets
# its own bounded ``max_examples``.
settings.register_profile("handover", derandomize=True, database=None, deadline=None,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("handover")


#: The xdist groups of the tests marked ``standin``, by what runs in real time. A rehearsal (a whole
#: rig: the stand-in controller at 500 Hz, the rig process and its ur_rtde worker, the LSL hand, a
#: session; tests/session and tests/ui): two or three at once on a 2-core machine starved each other
#: past the product's 0.1 s silence checks (CI, stop 26, when xdist ignored the groups: "no new state
#: for more than 0.1 s", tracker lost after 0.107 s), so the rehearsals run one at a time, on one
#: worker. Beside them, on another, one at a time too, the stand-in tests of tests/robot_io: a
#: stand-in and one client in the test's process, no rig, no session. Measured (58 tests, one at a
#: time at a load of 15-20): 1,150 s of wall time for 340 CPU-s, 0.3 of a core: they wait on the
#: clock; the rehearsals were ~75 % of the wall time. Both groups run beside the other workers'
#: tests, which their SCHED_FIFO preempts.
STANDIN_GROUPS = {"rehearsal": "standin-rehearsal", "ur": "standin-ur"}


def standin_group(item: pytest.Item) -> str:
    """The xdist group of a ``standin`` test (:data:`STANDIN_GROUPS`)."""
    under_robot_io = "robot_io" in item.path.relative_to(Path(__file__).parent).parts
    return STANDIN_GROUPS["ur" if under_robot_io else "rehearsal"]


#: The ceiling of a test not marked ``slow`` [s]: a hung one ends the run within minutes (the slow
#: ones, whole sessions on the wall clock, have pyproject's ``timeout``, 900 s; the slowest took
#: 153 s alone and 432 s at a load of 20). A ceiling for a hung test, not a measurement.
QUICK_TIMEOUT_S = 300


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests not marked ``slow`` get the ceiling :data:`QUICK_TIMEOUT_S`. Tests marked ``standin``
    share the worker of their :data:`STANDIN_GROUPS`. Tests that use a
    module-scoped fixture (a whole session run once, a study folder, a learner worker) share one
    xdist worker, so the fixture is built once, not once per worker that happens to draw one of them
    (``make test`` runs ``--dist loadgroup``). Slow tests go first. Runs before xdist reads the
    groups."""
    ceilings = config.pluginmanager.hasplugin("timeout")  # pytest-timeout (not with -p no:timeout)
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if ceilings and not item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(QUICK_TIMEOUT_S))
        if item.get_closest_marker("standin"):
            item.add_marker(pytest.mark.xdist_group(standin_group(item)))
            continue
        if info is None or item.get_closest_marker("xdist_group"):
            continue
        if any(defs[-1].scope == "module" for defs in info.name2fixturedefs.values() if defs):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
    # The slow tests first, slow browser tests (the longest) before them (a stable sort keeps each
    # module's order): xdist hands out tests in this order, so the longest ones start at once
    # instead of running alone at the end of a run.
    items.sort(key=lambda item: (item.get_closest_marker("slow") is None,
                                 item.get_closest_marker("browser") is None))


@pytest.fixture(scope="session")
def recorded_session(tmp_path_factory):
    """A short session on the wall clock recorded to XDF (support/recorded_session.py), run once per
    test process: the modules that use it are in its xdist group."""
    from support.recorded_session import record_session

    return record_session(tmp_path_factory.mktemp("recorded-session"))
