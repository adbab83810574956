"""A run of the suite ends, non-zero and naming the test, when a test crashes its worker, hangs, or
a worker hangs outside any test (issue 44; tests/support/watchdog.py).

Each case runs pytest in a subprocess on a small generated test folder, with the suite's own
configuration (pyproject's pytest table) and plugin, on two xdist workers with ``--dist loadgroup``
as ``make test`` runs them. Before the fix, the crash and the hung worker each left the
run waiting for good: the ceiling of the wait below is what failed, printing what the run had said.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from support.waiting import tail

ROOT = Path(__file__).resolve().parents[1]
#: A ceiling for the run's end (it ends in seconds; before the fix it never did).
CEILING_S = 180.0

NORMAL = '''
import pytest


@pytest.mark.parametrize("i", range(4))
def test_normal(i):
    assert i < 4
'''

CASES = {
    "crash": ({"test_case.py": '''
import os


def test_crashes_its_worker():
    os.abort()
'''}, [], ["worker 'gw", "crashed while running 'test_case.py::test_crashes_its_worker'"]),
    "hung test": ({"test_case.py": '''
import threading


def test_hangs():
    threading.Event().wait()
'''}, ["-o", "timeout=5"], ["crashed while running 'test_case.py::test_hangs'",
                           "Timeout (0:00:05)!", "in test_hangs"]),  # faulthandler's stacks
    # a worker that hangs after its last test, outside any test (here its session's end): the
    # controller waits for it for good
    "hung worker": ({"test_case.py": "def test_passes():\n    pass\n", "conftest.py": '''
import threading


def pytest_sessionfinish(session):
    if hasattr(session.config, "workerinput"):
        threading.Event().wait()
'''}, ["-o", "watchdog_idle=5"], ["watchdog ended the run: no test running",
                                 "pytest_sessionfinish (conftest.py:"]),  # py-spy's stack
}


def run_pytest(folder: Path, extra: list[str]) -> tuple[int, str]:
    """pytest on ``folder`` as ``make test`` runs it; its exit code and output, once it has ended."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "tests"),
                                                                    os.environ.get("PYTHONPATH")]))}
    process = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(folder),
         "-p", "no:cacheprovider", "-p", "support.watchdog", "-n", "2", "--dist", "loadgroup",
         *extra, str(folder)],
        cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True)  # its own process group: a run that never ends is killed whole
    try:
        output, _ = process.communicate(timeout=CEILING_S)
    except subprocess.TimeoutExpired as ended:
        os.killpg(process.pid, signal.SIGKILL)
        output, _ = process.communicate()
        raise AssertionError(f"the run had not ended after {CEILING_S:g} s; "
                             f"it said: {tail(output, 4000)}") from ended
    return process.returncode, output


@pytest.mark.parametrize("case", CASES)
def test_a_run_ends_non_zero_naming_the_test(tmp_path: Path, case: str) -> None:
    files, extra, expected = CASES[case]
    for name, source in files.items():
        (tmp_path / name).write_text(source)
    (tmp_path / "test_normal.py").write_text(NORMAL)
    code, output = run_pytest(tmp_path, extra)
    assert code != 0, f"the run passed: {tail(output)}"
    missing = [text for text in expected if text not in output]
    assert not missing, f"the run's output lacks {missing}: {tail(output, 4000)}"


LONG = '''
import time

import pytest


@pytest.mark.timeout(120)
def test_long_with_its_own_ceiling():
    time.sleep(6)


def test_long_under_the_runs_ceiling():
    time.sleep(6)
'''


@pytest.mark.parametrize("ceiling", ["its own mark", "--timeout=0"])
def test_a_test_within_its_own_ceiling_is_not_taken_for_a_hang(tmp_path: Path, ceiling: str) -> None:
    """Tests that run 6 s without a word, in a run whose ceiling (2 s) and idle limit (2 s) they
    pass: one with its own ``timeout`` mark (120 s), and, with ``--timeout=0`` (no ceiling, as
    ``make soak``'s stress run), one without. Both pass. Before the fix the watchdog took the run's
    ceiling for every test and ``--timeout=0`` for "not given", and ended both runs as hung (so it
    ended ``make soak``'s 500-cycle stress run after 17 minutes)."""
    (tmp_path / "test_case.py").write_text(LONG)
    selection = {"its own mark": ["-k", "own_ceiling"], "--timeout=0": ["--timeout=0"]}[ceiling]
    code, output = run_pytest(tmp_path, ["-o", "timeout=2", "-o", "watchdog_idle=2", *selection])
    assert code == 0 and "watchdog" not in output, tail(output, 4000)


def test_a_slow_test_without_a_docstring_is_named_at_the_end(tmp_path: Path) -> None:
    """With the threshold at 0.2 s: a test that waits 0.3 s without a docstring is named, one with
    a docstring and a quick one are not (tests/support/slow_tests.py)."""
    (tmp_path / "test_case.py").write_text('''
import time


def test_slow_and_silent():
    time.sleep(0.3)


def test_slow_and_says_why():
    """Waits 0.3 s: the point of this test."""
    time.sleep(0.3)


def test_quick():
    pass
''')
    code, output = run_pytest(tmp_path, ["-o", "slow_test_s=0.2", "-p", "support.slow_tests"])
    assert code == 0, tail(output)
    named = [line for line in output.splitlines() if line.strip().endswith(("_silent", "_why", "quick"))]
    assert "tests over 0.2 s without a docstring saying why: 1" in output, tail(output)
    assert [line.split()[-1] for line in named] == ["test_case.py::test_slow_and_silent"], named
