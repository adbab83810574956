"""CPU seconds of one ``handover`` command's start (``handover --help``: every subcommand's module
is imported to build the parser, so every command pays this, and the test suite pays it at every
command it starts). Figures are the child's user + system time, so they hold on a loaded
machine, where wall time does not.

Baselines of the same run: a bare interpreter (``python -c pass``), and the same start with the
modules that commands now import only when they need them imported up front (viser: serve only;
scipy.stats: the validation phase's Sobol points, a late learner's fallback), as before.

Usage: ``.venv/bin/python benchmarks/command_start.py [--runs 9]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

DEFERRED = "import scipy.stats, viser"
HELP = "from app.cli import main; main(['--help'])"


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
    runs = {name: [] for name in ("bare interpreter", "handover --help", "with the deferred imports")}
    for _ in range(args.runs):  # interleaved: a change of the machine's load touches all three
        runs["bare interpreter"].append(cpu_seconds("pass"))
        runs["handover --help"].append(cpu_seconds(HELP))
        runs["with the deferred imports"].append(cpu_seconds(f"{DEFERRED}; {HELP}"))
    medians = {name: statistics.median(seconds) for name, seconds in runs.items()}
    for name, median in medians.items():
        print(f"{name:>26}: median {median:.2f} s CPU over {args.runs} runs")
    saved = medians["with the deferred imports"] - medians["handover --help"]
    print(f"deferring saves {saved:.2f} s CPU per command start (ratio "
          f"{medians['with the deferred imports'] / medians['handover --help']:.2f}×)")


if __name__ == "__main__":
    main()
