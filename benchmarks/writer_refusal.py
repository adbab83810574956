"""Seconds from a second writer's process start to its refusal, while a first writer holds the
participant (issue 12: within 1 s).

The first writer is ``handover run-session`` on the paper's protocol (simulated time, so it also
loads the machine as a session does). The second is ``handover run-session --resume`` on the same
participant; it is timed from ``Popen`` to its exit with the refusal. Baselines of the same run:
a bare interpreter start (``python -c pass``), and the imports the refusal waited for before the
command line took the lock first (the run-session command's modules: learner client, rig, engine,
pandas) — which is when the old check came.

Usage: ``.venv/bin/python benchmarks/writer_refusal.py [--runs 11]``
"""

from __future__ import annotations

import argparse
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HANDOVER = [sys.executable, "-m", "app.cli"]


def _timed(command: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    began = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    return time.perf_counter() - began, done


def _events(path: Path) -> int:
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
            return conn.execute("SELECT count(*) FROM events").fetchone()[0]
    except sqlite3.Error:
        return 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=11)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        study = Path(folder)
        first = subprocess.Popen([*HANDOVER, "run-session", "--study", str(study), "--participant",
                                  "B01", "--scenario", "perturbed", "--auto", "--seed", "1",
                                  "--no-progress"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        try:
            while _events(study / "B01.sqlite") < 3:
                time.sleep(0.05)
            refusals = []
            for _ in range(args.runs):
                seconds, done = _timed([*HANDOVER, "run-session", "--study", str(study),
                                        "--participant", "B01", "--auto", "--resume"])
                assert done.returncode == 2 and f"pid {first.pid}" in done.stderr, done.stderr
                refusals.append(seconds)
            bare = [_timed([sys.executable, "-c", "pass"])[0] for _ in range(args.runs)]
            imports = [_timed([sys.executable, "-c", "import app.session.run_session"])[0]
                       for _ in range(args.runs)]
            still_running = first.poll() is None
        finally:
            first.kill()
            first.wait()
    refusal, start, old = (statistics.median(x) for x in (refusals, bare, imports))
    print(f"second writer refused after (median of {args.runs}): {refusal:.3f} s "
          f"(min {min(refusals):.3f}, max {max(refusals):.3f}); first writer still running: "
          f"{still_running}")
    print(f"baseline, bare interpreter start:                 {start:.3f} s")
    print(f"baseline, the command's imports (old check point): {old:.3f} s "
          f"(refusal / imports = {refusal / old:.2f})")


if __name__ == "__main__":
    main()
