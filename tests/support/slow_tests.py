"""A test that takes more than :data:`SLOW_S` seconds says why in its docstring: the end of a run
names those that took longer and have none (their setup, call and teardown together).

A list, not a failure: a test's time is the machine's as much as the test's (tests wait for
states, never assert a time), and the list is read where the 25 slowest tests are.
"""

from __future__ import annotations

import unittest
from collections import defaultdict

import pytest

#: Default of the ``slow_test_s`` ini option: seconds past which a test's docstring says why it
#: takes so long (the developers' guide).
SLOW_S = 20.0
#: The key, in a teardown report's ``user_properties``, of whether the test has a docstring (xdist
#: carries it from a worker to the controller, which has no test items).
KEY = "has_docstring"

_seconds: defaultdict[str, float] = defaultdict(float)
_documented: dict[str, bool] = {}


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini("slow_test_s", f"seconds past which a test's docstring says why it takes so long "
                                 f"(default {SLOW_S:g})", default=str(SLOW_S))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    if call.when == "teardown":
        function = getattr(item, "function", None)
        # a unittest-style test (Hypothesis's state machines) says it in its class's docstring
        cls = getattr(item, "cls", None)
        doc = (getattr(function, "__doc__", None) or "").strip() or (
            (cls.__doc__ or "").strip() if cls and issubclass(cls, unittest.TestCase) else "")
        documented = bool(doc)
        outcome.get_result().user_properties.append((KEY, documented))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _seconds[report.nodeid] += report.duration
    for key, value in report.user_properties:
        if key == KEY:
            _documented[report.nodeid] = bool(value)


def pytest_terminal_summary(terminalreporter) -> None:
    slow = float(terminalreporter.config.getini("slow_test_s"))
    silent = sorted(((seconds, nodeid) for nodeid, seconds in _seconds.items()
                     if seconds > slow and not _documented.get(nodeid, True)), reverse=True)
    if not silent:
        return
    terminalreporter.write_sep("=", f"tests over {slow:g} s without a docstring saying why: "
                                    f"{len(silent)}", yellow=True)
    for seconds, nodeid in silent:
        terminalreporter.write_line(f"{seconds:8.2f}s  {nodeid}")
