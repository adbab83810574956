"""The study's LSL outlets recorded as a lab records them, and ``handover report --xdf`` on it.

A session on the mock arm on the wall clock (the short protocol: 9 handovers, Sobol, learned and θ*
trials) publishes its robot and marker streams; a stand-in eye tracker publishes a pupil diameter
that dilates 0.3 s after the robot starts, varying from trial to trial, with noise; the suite's
recorder and a real LabRecorder record all three to XDF (tests/support/recorded_session.py). It
prints how the recording agrees with the SQLite rows — the baseline is one control period (8 ms at
125 Hz) — and runs ``handover report --xdf``; the pupil figure is the one in docs/analysis.md.

    python benchmarks/lsl_outlets.py [--out out/lsl-outlets]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.engine import SHORT_PROTOCOL
from support.recorded_session import agreement, record_session

from app.cli import main as handover


def run(out: Path) -> int:
    with tempfile.TemporaryDirectory() as folder:
        session = record_session(Path(folder), SHORT_PROTOCOL, pupil_spread=0.25, pupil_noise_mm=0.03,
                                 lsl_name=f"benchmark{os.getpid()}")
        found = agreement(session)
        period = 1 / session.rate_hz
        counts = found.robot_counts.values()
        print(f"markers: {len(found.recorded)} recorded, {len(found.stored)} events stored; "
              f"max |marker − stored time| {found.marker_error_s * 1e6:.0f} µs "
              f"(baseline: one control period, {period * 1e3:.0f} ms)")
        print(f"robot: {sum(r for r, _ in counts)} samples recorded, {sum(s for _, s in counts)} rows "
              f"stored in {len(found.robot_counts)} trials, values equal: {found.robot_equal}; "
              f"max |sample − (go + t)| {found.robot_error_s * 1e6:.0f} µs; median rate "
              f"{found.rate_hz:.1f} Hz (nominal {session.rate_hz} Hz)")
        print(f"LabRecorder: {found.labrecorder_markers} of {len(found.recorded)} markers (it does "
              "not pull again when stopped)")
        return handover(["report", str(session.study), "--out", str(out), "--xdf", str(session.xdf),
                         "--xdf-stream", session.pupil])


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/lsl-outlets"), help="the report's folder")
    sys.exit(run(parser.parse_args().out))
