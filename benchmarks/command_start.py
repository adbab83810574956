"""CPU seconds of a process's start: one ``handover`` command (``handover --help``: every
subcommand's module is imported to build the parser, so every command pays this, and the test suite
pays it at every command it starts), and the processes a rig spawns for a session (the rig process,
and in a rehearsal the hand publisher), which import their modules afresh. Figures are the child's
user + system time, so they hold on a loaded machine, where wall time does not.

Baselines of the same run: a bare interpreter (``python -c pass``), and each start with the modules
that these processes now import only when they need them imported up front, as before (viser: serve
only; pandas: export and report only, sqlite_utils no longer pulls it in; scipy.stats: the
validation phase's Sobol points, a late learner's fallback; scipy.linalg: the distance filter's
exp(A·dt), now in closed form; scipy.spatial: rotation vectors, which only the UR stand-in's
kinematics need).

Usage: ``.venv/bin/python benchmarks/command_start.py [--runs 9]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

#: What the robot's processes imported when they started, and no longer do.
KINEMATICS = "import scipy.linalg, scipy.spatial.transform"
#: What each process imports when it starts, and what it imported besides before.
STARTS = {"handover --help": ("from app.cli import main; main(['--help'])",
                              f"import scipy.stats, viser, pandas; {KINEMATICS}"),
          "rig process": ("import robot_io.rig.process", KINEMATICS),
          "hand publisher": ("import robot_io.standins.hand_publisher", KINEMATICS)}


def cpu_seconds(code: str) -> float:
    """The user + system CPU time of ``python -c code`` (its output discarded)."""
    before = os.times()
    subprocess.run([sys.executable, "-c", code], stdout=subprocess.DEVNULL, check=False, timeout=300)
    after = os.times()
    return (after.children_user - before.children_user) + (after.children_system
                                                           - before.children_system)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9)
    args = parser.parse_args()
    bare: list[float] = []
    now: dict[str, list[float]] = {name: [] for name in STARTS}
    before: dict[str, list[float]] = {name: [] for name in STARTS}
    for _ in range(args.runs):  # interleaved: a change of the machine's load touches all of them
        bare.append(cpu_seconds("pass"))
        for name, (code, deferred) in STARTS.items():
            now[name].append(cpu_seconds(code))
            before[name].append(cpu_seconds(f"{deferred}; {code}"))
    print(f"{'bare interpreter':>16}: median {statistics.median(bare):.2f} s CPU over {args.runs} runs")
    for name in STARTS:
        start, eager = statistics.median(now[name]), statistics.median(before[name])
        print(f"{name:>16}: median {start:.2f} s CPU; with the deferred imports {eager:.2f} s: "
              f"deferring saves {eager - start:.2f} s per start (ratio {eager / start:.2f}×)")

if __name__ == "__main__":
    main()
