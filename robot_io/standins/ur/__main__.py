"""``python -m robot_io.standins.ur --host 127.0.0.5 [--series cb3|e]``: run a stand-in UR controller.

Prints ``ready <host>`` on stdout once every port listens, then runs until terminated (SIGTERM,
Ctrl-C) or, with ``--exit-with-stdin``, until its standard input closes — so a stand-in started by a
test never outlives the test process.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

from robot_io.clock import SUPPORT_PRIORITY, raise_priority
from robot_io.standins.ur.control import DEFAULT_PORT
from robot_io.standins.ur.model import Series
from robot_io.standins.ur.standin import StandinController


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m robot_io.standins.ur", description=__doc__)
    parser.add_argument("--host", default="127.0.0.2", help="loopback address to listen on")
    parser.add_argument("--series", choices=("cb3", "e"), default="cb3",
                        help="cb3: CB-series, 125 Hz; e: e-Series, 500 Hz")
    parser.add_argument("--control-port", type=int, default=DEFAULT_PORT, help="JSON-lines control port")
    parser.add_argument("--exit-with-stdin", action="store_true",
                        help="exit when standard input closes (the parent process ended)")
    parser.add_argument("--realtime-priority", action="store_true",
                        help="run the controller cycle under SCHED_FIFO (root or CAP_SYS_NICE): "
                             "a real controller has hardware of its own")
    parser.add_argument("-v", "--verbose", action="store_true", help="log at INFO level")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s stand-in %(levelname)s %(message)s")
    if args.realtime_priority:
        raise_priority(SUPPORT_PRIORITY)  # before the threads start: they inherit it
    series = Series.CB3 if args.series == "cb3" else Series.E_SERIES
    standin = StandinController(args.host, series, control_port=args.control_port)
    signal.signal(signal.SIGTERM, lambda *_: standin.close())
    if args.exit_with_stdin:
        def close_at_end_of_stdin() -> None:
            sys.stdin.read()
            standin.close()

        threading.Thread(target=close_at_end_of_stdin, daemon=True).start()
    print(f"ready {args.host}", flush=True)
    try:
        standin.wait()
    except KeyboardInterrupt:
        standin.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
