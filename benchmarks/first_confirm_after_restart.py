"""The first Confirm on the tablet after a restart of `handover serve`.

A participant's session stopped at a placement (the scale on the tablet) is resumed by a fresh
`handover serve --participant` process, as after a Ctrl-C and a restart: the tablet is paired, the
handle dragged, Confirm tapped. Printed: the seconds from the tap until the scale has gone from the
tablet (the placement is stored before the next screen is published), median and max of ``RUNS``
restarts (goal: within 1 s of the tap), and, as the baseline of the same run, the same Confirm's
seconds on the next placement of the same process (a learner already running).

    python benchmarks/first_confirm_after_restart.py [RUNS]
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.browser import (
    chromium,
    confirm_placement,
    open_screens,
    run_trial,
    serve,
    tablet_screen,
    touch_drag_to,
)
from support.engine import closed_session

from app.protocol.state import Step

RUNS = 10
CODE = "S01"


def stopped_at_a_placement(folder: Path) -> Path:
    """A study whose participant waits for the placement of its first handover (the short
    protocol, closed as a restart leaves it)."""
    study = folder / "template" / "study"
    closed_session(study, CODE, until=Step.PLACE)
    return study


def one_restart(template: Path, folder: Path) -> tuple[float, float]:
    """A fresh server resumes the participant; (first Confirm, the next placement's Confirm) [s]."""
    shutil.copytree(template, folder / "study")
    with serve(folder, "--participant", CODE, verbose=False) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        assert tablet_screen(tablet) == "place", "the resumed session does not wait for a placement"
        touch_drag_to(tablet, 0.2)
        first = confirm_placement(tablet)
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.8)
        later = confirm_placement(tablet)
        served.shutdown()
    return first, later


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else RUNS
    with tempfile.TemporaryDirectory() as tmp:
        template = stopped_at_a_placement(Path(tmp))
        results = [one_restart(template, Path(tmp) / f"run{i}") for i in range(runs)]
    for label, seconds in (("first Confirm after a restart", [r[0] for r in results]),
                           ("baseline: the next placement's Confirm", [r[1] for r in results])):
        ms = [1e3 * s for s in seconds]
        print(f"{label} -> scale gone: median {statistics.median(ms):.0f} ms, max {max(ms):.0f} ms "
              f"over {len(ms)} restarts (goal: within 1000 ms)", flush=True)


if __name__ == "__main__":
    main()
