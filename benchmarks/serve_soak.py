"""A `handover serve` session of at least 15 minutes with the simulated participant: memory and
open files flat (issue 45, item 12).

Runs `handover serve --auto-participant` with a bare lab configuration's defaults (the mock arm at
500 Hz, the simulated hand, the paper's protocol of 34 interactions), with the dashboard and the
paired tablet open in headless Chromium; the simulated experimenter presses Start trial each time
the dashboard says it is ready, participant after participant (End session when one is complete,
then the next code, with "Simulated participant rates" ticked again), until ``--minutes`` have
passed. Every ``--every`` seconds a sampler reads, of
the serve process: its resident memory (VmRSS), its open file descriptors, its threads; and the
resident memory of its child processes together (the rig process, the learner's worker and its
forkserver).

Printed: one line per sample (as it is taken), then the run's own baseline against its end — the
median of the ``--window`` minutes after the warm-up (the first participant's whole session: its
imports, its learner's first fits, the end of its learning batches, where the serve process grew
by some 60 MB once in the run of README.md, the pages' first messages) against
the median of the last ``--window`` minutes — and the least-squares slope after the warm-up, per
hour. ``--from-log`` prints the same of a run's printed samples without running again. Flat: the
end within a few MB and a handful of descriptors of the baseline, and a slope that would not fill
memory in a day of sessions.

    nice -n 19 .venv/bin/python benchmarks/serve_soak.py --minutes 15 > /tmp/serve_soak.log
"""

from __future__ import annotations

import argparse
import contextlib
import re
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.browser import (
    chromium,
    click,
    keep_starting,
    open_participant,
    open_screens,
    serve,
    tick,
    wait_text,
)

#: The dashboard's count of the open session ("12 of 34 handovers completed").
COMPLETED = re.compile(r"(\d+) of \d+ handovers completed")


@dataclass(frozen=True)
class Sample:
    t_s: float  # since the first participant opened
    participants: int  # opened so far
    handovers: int  # completed so far, all participants
    rss_mb: float
    fds: int
    threads: int
    children_mb: float


class Sampler:
    """Samples ``pid`` every ``every_s`` on a thread of its own until :meth:`stop`."""

    def __init__(self, pid: int, every_s: float) -> None:
        self.process, self.every_s = psutil.Process(pid), every_s
        self.samples: list[Sample] = []
        self.participants, self.handovers, self._done_before = 0, 0, 0
        self._began = time.monotonic()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sampler", daemon=True)

    def start(self) -> None:
        self._began = time.monotonic()
        self._thread.start()

    def counted(self, open_session: int) -> None:
        """The open session's completed handovers (the page's count)."""
        self.handovers = self._done_before + open_session

    def next_participant(self) -> None:
        self._done_before, self.participants = self.handovers, self.participants + 1

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            with self.process.oneshot():
                rss, fds = self.process.memory_info().rss, self.process.num_fds()
                threads = self.process.num_threads()
            children = 0
            for child in self.process.children(recursive=True):
                with contextlib.suppress(psutil.NoSuchProcess):  # ended since it was listed
                    children += child.memory_info().rss
            sample = Sample(time.monotonic() - self._began, self.participants, self.handovers,
                            rss / 2**20, fds, threads, children / 2**20)
            self.samples.append(sample)
            print(f"{sample.t_s:7.0f} s  participants {sample.participants:2d}  handovers "
                  f"{sample.handovers:4d}  RSS {sample.rss_mb:7.1f} MB  fds {sample.fds:4d}  "
                  f"threads {sample.threads:3d}  children {sample.children_mb:7.1f} MB",
                  flush=True)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def run(minutes: float, every_s: float) -> list[Sample]:
    """The soak: participants one after another until ``minutes`` have passed."""
    end = time.monotonic() + 60 * minutes
    with tempfile.TemporaryDirectory(prefix="serve-soak-") as tmp, \
            serve(Path(tmp), "--auto-participant", rate=500, protocol_toml="",
                  verbose=False) as served, chromium() as browser:
        dashboard, _tablet = open_screens(browser, served)
        sampler = Sampler(served.process.pid, every_s)
        sampler.start()
        try:
            while time.monotonic() < end:
                sampler.next_participant()
                open_participant(dashboard, f"S{sampler.participants:02d}")
                if sampler.participants > 1:  # End session switched the simulated participant off
                    tick(dashboard, "Simulated participant rates", "simulated participant on")

                def finished() -> bool | None:
                    text = dashboard.inner_text("body")
                    if (count := COMPLETED.search(text)) is not None:
                        sampler.counted(int(count[1]))
                    return "Session complete" in text or time.monotonic() >= end or None

                keep_starting(dashboard, finished, timeout_s=60 * minutes + 600)
                if time.monotonic() < end:
                    click(dashboard, "End session")
                    wait_text(dashboard, "A known code resumes its session")
        finally:
            sampler.stop()
        served.shutdown()
    return sampler.samples


#: A sample as :class:`Sampler` prints it.
SAMPLE_LINE = re.compile(r"^\s*([\d.]+) s  participants\s+(\d+)  handovers\s+(\d+)  RSS\s+([\d.]+) MB"
                         r"  fds\s+(\d+)  threads\s+(\d+)  children\s+([\d.]+) MB$", re.M)


def read_log(path: Path) -> list[Sample]:
    """The samples a run printed."""
    return [Sample(float(t), int(p), int(h), float(rss), int(fds), int(threads), float(children))
            for t, p, h, rss, fds, threads, children in SAMPLE_LINE.findall(path.read_text())]


def report(samples: list[Sample], window_min: float) -> None:
    """The baseline (the window after the warm-up: the first participant's session) against the
    end (the last window), and the slopes after the warm-up."""
    began = next((s.t_s for s in samples if s.participants > 1), None)
    if began is None:
        raise SystemExit("the run ended within its first participant's session: no baseline after "
                         "the warm-up (run longer)")
    warm = [s for s in samples if s.t_s >= began]
    first = [s for s in warm if s.t_s <= began + 60 * window_min]
    last = [s for s in warm if s.t_s >= samples[-1].t_s - 60 * window_min]
    t = np.array([s.t_s for s in warm]) / 3600
    print(f"\n{samples[-1].t_s / 60:.1f} min, {samples[-1].participants} participants, "
          f"{samples[-1].handovers} handovers, {len(samples)} samples; from the second "
          f"participant ({began / 60:.1f} min), medians of the first and the last {window_min:g} "
          "min, and the least-squares slope:")
    for name, unit in (("rss_mb", "MB"), ("fds", ""), ("threads", ""), ("children_mb", "MB")):
        values = np.array([getattr(s, name) for s in warm], dtype=float)
        base = statistics.median(getattr(s, name) for s in first)
        end = statistics.median(getattr(s, name) for s in last)
        slope = np.polyfit(t, values, 1)[0] if len(samples) > 2 else float("nan")
        print(f"  {name:12s} baseline {base:8.1f} {unit:2s}  end {end:8.1f} {unit:2s}  "
              f"change {end - base:+7.1f} {unit:2s}  slope {slope:+8.1f} {unit}/h  "
              f"(min {values.min():.1f}, max {values.max():.1f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=15.0, help="how long the soak runs")
    parser.add_argument("--every", type=float, default=10.0, help="seconds between samples")
    parser.add_argument("--window", type=float, default=3.0,
                        help="minutes of the baseline and of the end compared")
    parser.add_argument("--from-log", type=Path,
                        help="report the samples a run printed to this file (no new run)")
    args = parser.parse_args()
    samples = read_log(args.from_log) if args.from_log else run(args.minutes, args.every)
    report(samples, args.window)


if __name__ == "__main__":
    main()
