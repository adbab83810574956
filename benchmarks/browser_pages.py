"""What opening a page costs the suite's Chromium: with the suite's switches (tests/support/browser:
the omnibox's WebUI popup off) against Playwright's switches alone (the baseline), in one run.

    python benchmarks/browser_pages.py [--rounds 5] [--pages 4]

One `handover serve` (the short protocol, no participant) serves both screens. Each round starts
Chromium, opens ``--pages`` dashboards and as many tablets (a context each, as the browser tests
do), waits until each has drawn, then closes Chromium. Prints per variant the median CPU-seconds of
a round for all of Chromium's processes and per page opened, and the ratio of the two variants.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from playwright.sync_api import sync_playwright
from support.browser import CHROMIUM, DISABLED_FEATURES, chromium_args, open_page, serve
from support.cpu import TreeCpu


def chromium_cpu() -> float:
    """User + system seconds of the live Chromium processes of this process's tree (support.cpu's
    reading of the tree, by the kind of each process)."""
    tree = TreeCpu()
    return sum(seconds for key, seconds in tree.sample().items()
               if tree.kinds[key].startswith("Chromium"))


def round_cpu(args: list[str], dashboard_url: str, tablet_url: str, pages: int) -> float:
    """One round's CPU-seconds of Chromium, read just before it closes (its launch included)."""
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=args)
        try:
            for _ in range(pages):
                open_page(browser, dashboard_url, size=(1400, 900))
                open_page(browser, tablet_url, touch=True)
            return chromium_cpu()
        finally:
            browser.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--pages", type=int, default=4, help="dashboards (and as many tablets) a round")
    options = parser.parse_args()
    suite = chromium_args()
    playwrights = [word for word in suite if not word.startswith("--disable-features=")]
    variants = {"Playwright's switches (baseline)": playwrights, "the suite's switches": suite}
    with tempfile.TemporaryDirectory() as tmp, serve(Path(tmp)) as served:
        seconds: dict[str, list[float]] = {name: [] for name in variants}
        for _ in range(options.rounds):  # interleaved: a slower minute of the machine hits both
            for name, args in variants.items():
                seconds[name].append(round_cpu(args, served.dashboard_url, served.tablet_url,
                                               options.pages))
    opened = 2 * options.pages
    print(f"{options.rounds} rounds of {opened} pages (Chromium started in each); suite's own "
          f"features off: {', '.join(DISABLED_FEATURES)}")
    medians = {name: statistics.median(values) for name, values in seconds.items()}
    for name, median in medians.items():
        print(f"  {name}: median {median:.2f} CPU-s a round ({median / opened:.2f} a page; "
              f"rounds {', '.join(f'{value:.2f}' for value in seconds[name])})")
    baseline, suite_s = medians.values()
    print(f"  ratio suite/baseline: {suite_s / baseline:.2f}; saved per page: "
          f"{(baseline - suite_s) / opened:.2f} CPU-s")


if __name__ == "__main__":
    main()
