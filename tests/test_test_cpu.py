"""``HANDOVER_TEST_CPU=1`` (tests/support/cpu.py) sums the run's CPU by the kind of process that
used it: the test process, a spawned child (a rig), Chromium's renderers, a learner's forkserver.
The suite's time is its CPU on two cores, and these sums say where a change of design would save
it."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: A test that burns CPU in its own process and in a spawned child (as a rig is started), and has
#: the sampler read the child after its burn, before the child ends.
BURNING_TEST = '''
import multiprocessing as mp
import time

from support import cpu


def burn(seconds):
    start = time.process_time()
    while time.process_time() - start < seconds:
        pass


def child(burned, done):
    burn({child_s})
    burned.set()
    done.wait()


def test_burns():
    context = mp.get_context("spawn")
    burned, done = context.Event(), context.Event()
    process = context.Process(target=child, args=(burned, done))
    process.start()
    burn({own_s})
    assert burned.wait(60), "the child did not burn its CPU within 60 s"
    cpu._tree.sample()  # the child's burn, read while it is alive
    done.set()
    process.join()
'''
CHILD_S, OWN_S = 1.5, 0.6
LINE = re.compile(r"^\s*([\d.]+)s  (.+)$", re.M)


def test_the_runs_cpu_is_summed_by_the_kind_of_process(tmp_path: Path) -> None:
    (tmp_path / "test_burning.py").write_text(BURNING_TEST.format(child_s=CHILD_S, own_s=OWN_S))
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "support.cpu",
         "--rootdir", str(tmp_path), str(tmp_path / "test_burning.py")],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
        env={**os.environ, "HANDOVER_TEST_CPU": "1", "PYTHONPATH": str(ROOT / "tests")})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "CPU by kind of process" in run.stdout, run.stdout
    by_kind = {name: float(seconds) for seconds, name in
               LINE.findall(run.stdout.split("CPU by kind of process", 1)[1])}
    spawned = by_kind.get("spawned processes (rigs, Dask workers, resource trackers)", 0.0)
    assert spawned >= CHILD_S * 0.9, run.stdout
    assert by_kind.get("the test process", 0.0) >= OWN_S * 0.9, run.stdout
    [(total, _)] = [(float(s), n) for s, n in LINE.findall(run.stdout) if "test_burns" in n]
    assert total >= sum(by_kind.values()) - 0.05, run.stdout  # every kind is the test's
