"""`make soak`: the tests that meet the machine's timing, run N times beside a CPU hog.

The browser, rehearsal, rig-process and kill tests (marker ``soak``, plus ``browser``) start servers,
browsers, stand-in controllers and processes that are killed; they are where a wait on the clock
would show. This runs them ``--runs`` times (default 10) as ``make test`` runs them (the same xdist
workers), with ``yes > /dev/null`` keeping one core busy the whole time, and prints each test's pass
count, the failures' first lines, and the wall time of each run. Before them, once, the lifetime
stress tests (marker ``stress``: shared objects opened and released in a loop while other threads use
them) run with ``--stress-cycles`` cycles each (default 500) beside the same hog. It is not part of
CI: run it before saying that the suite is steady.

A soak takes hours (the rehearsal's 500 stress cycles alone about one on the wall clock). With
``--until HH:MM`` it starts no soak run that would not end by then (judged by its longest run so
far) and reports the runs it made; without it, all ``--runs``.

    make soak [SOAK_RUNS=10] [SOAK_HOGS=1] [SOAK_UNTIL=HH:MM] [SOAK_STRESS_CYCLES=500] [PYTEST_WORKERS=4]
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import psutil

SELECTION = "(browser or soak) and not stress"
#: The lifetime stress tests read their cycles from this variable (tests/support/lifetimes.py).
STRESS_CYCLES = "HANDOVER_STRESS_CYCLES"


def run_once(junit: Path, workers: str, extra: list[str], selection: str = SELECTION,
             env: dict[str, str] | None = None) -> float:
    """One pytest run of ``selection``; its wall time [s]."""
    began = time.monotonic()
    with subprocess.Popen([sys.executable, "-m", "pytest", "-m", selection, "-n", workers,
                           "--dist", "loadgroup", "-p", "no:cacheprovider", "-q", "--no-header",
                           f"--junitxml={junit}", *extra], env=env) as run:
        try:
            run.wait()
        except BaseException:  # SIGTERM or Ctrl-C: the run's workers, servers and browsers go too
            end_tree(run.pid)
            raise
    return time.monotonic() - began


def end_tree(pid: int) -> None:
    """Kill ``pid`` and every process it started (a killed pytest left its xdist workers, and
    they their servers and browsers, running on)."""
    try:
        root = psutil.Process(pid)
        processes = [root, *root.children(recursive=True)]
    except psutil.NoSuchProcess:
        return
    for process in processes:
        with contextlib.suppress(psutil.Error):  # ended since it was listed
            process.kill()
    psutil.wait_procs(processes, timeout=30)


def outcomes(junit: Path) -> dict[str, str]:
    """Test id → "passed", "failed", "error" or "skipped", read from a JUnit XML report."""
    result = {}
    for case in ET.parse(junit).iter("testcase"):
        name = f"{case.get('classname')}::{case.get('name')}"
        kinds = [child.tag for child in case if child.tag in ("failure", "error", "skipped")]
        result[name] = {"failure": "failed"}.get(kinds[0], kinds[0]) if kinds else "passed"
    return result


def deadline(until: str | None) -> float:
    """``HH:MM`` (today, or tomorrow when that is past) as a ``time.monotonic()`` moment; none: inf."""
    if not until:
        return float("inf")
    try:
        at = datetime.datetime.combine(datetime.date.today(),
                                       datetime.time.fromisoformat(until))
    except ValueError as bad:
        raise SystemExit(f"--until: {until!r} is not a time of day HH:MM ({bad})") from None
    now = datetime.datetime.now()
    if at <= now:
        at += datetime.timedelta(days=1)
    return time.monotonic() + (at - now).total_seconds()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--hogs", type=int, default=1, help="cores kept busy by `yes > /dev/null`")
    parser.add_argument("--workers", default="3")
    parser.add_argument("--stress-cycles", type=int, default=500,
                        help="cycles of each lifetime stress test (run once, before the soak runs; "
                             "0: no stress run)")
    parser.add_argument("--until", help="start no soak run that would not end by HH:MM")
    parser.add_argument("pytest_args", nargs="*", help="passed on to pytest (e.g. -k rehearsal)")
    args = parser.parse_args()
    ends_by = deadline(args.until)
    passed, ran, seconds = Counter(), Counter(), []
    # a soak stopped with SIGTERM (kill, pkill) ends its hogs and its pytest run's processes too:
    # on Python's default action they outlived it and doubled the next soak's load
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))

    def count(run: dict[str, str]) -> int:
        """Adds one run's outcomes to the counts; how many passed."""
        for name, outcome in run.items():
            if outcome != "skipped":
                ran[name] += 1
                passed[name] += outcome == "passed"
        return sum(outcome == "passed" for outcome in run.values())

    hogs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(args.hogs)]
    try:
        with tempfile.TemporaryDirectory(prefix="soak-") as folder:
            if args.stress_cycles:
                junit = Path(folder) / "stress.xml"
                # no run-wide ceiling (each stress test carries its own: tests/support/lifetimes.py)
                took = run_once(junit, args.workers, ["--timeout=0", *args.pytest_args], "stress",
                                {**os.environ, STRESS_CYCLES: str(args.stress_cycles)})
                print(f"stress run ({args.stress_cycles} cycles each): {took:.0f} s, "
                      f"{count(outcomes(junit))} passed", flush=True)
            for i in range(args.runs):
                if time.monotonic() + max(seconds, default=0.0) > ends_by:
                    print(f"soak run {i + 1}/{args.runs} not started: it would not end by "
                          f"{args.until}", flush=True)
                    break
                junit = Path(folder) / f"run-{i}.xml"
                seconds.append(run_once(junit, args.workers, args.pytest_args))
                print(f"soak run {i + 1}/{args.runs}: {seconds[-1]:.0f} s, "
                      f"{count(outcomes(junit))} passed", flush=True)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    width = max(map(len, ran), default=10)
    print(f"\n{'test':<{width}}  passed/runs")
    for name in sorted(ran, key=lambda n: (passed[n] - ran[n], n)):
        print(f"{name:<{width}}  {passed[name]}/{ran[name]}")
    steady = sum(passed[n] == ran[n] for n in ran)
    timing = (f"; run wall time median {sorted(seconds)[len(seconds) // 2]:.0f} s "
              f"(min {min(seconds):.0f}, max {max(seconds):.0f})" if seconds else "")
    print(f"\n{steady} of {len(ran)} tests passed every run ({len(seconds)} of {args.runs} soak "
          f"runs, {'1 stress run' if args.stress_cycles else 'no stress run'}){timing}")
    return 0 if steady == len(ran) else 1


if __name__ == "__main__":
    sys.exit(main())
