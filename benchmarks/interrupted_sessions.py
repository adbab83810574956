"""Headless sessions interrupted by Ctrl-C at random moments: how many crashed, printed a
traceback or hung (issue: "no crash, no hang"; docs/architecture.md, "Shared objects and their
lifetimes").

Each run starts ``handover run-session --auto --realtime`` (or ``--rehearse``) on a fresh study
folder, sends SIGINT after a delay drawn uniformly from [--earliest, --latest] s, and waits for the
command to end. The SIGINT goes to the command's process group, the rig, learner and stand-ins it
started included, as a terminal's Ctrl-C does (``--to pid``: to the command alone, as ``kill -INT``).
A run that ends by a signal (a segmentation fault: -11, or 139 from a shell), prints
"Traceback" or "Fatal Python error", or has not ended --hang-after seconds after the SIGINT (then
killed) is counted. Beside it, ``yes > /dev/null`` keeps a core busy (--hogs). ``--source DIR`` runs
another checkout's code with this environment (PYTHONPATH), for the baseline of the same run:

    .venv/bin/python benchmarks/interrupted_sessions.py --runs 50 --mode realtime
    .venv/bin/python benchmarks/interrupted_sessions.py --runs 50 --mode rehearse --source ../before
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

#: What a close may print, and what it must not.
CRASH_WORDS = ("Traceback", "Fatal Python error", "Segmentation fault")
#: What is counted of each run.
KINDS = ("crashed", "traceback", "hung", "other exit")


def one_run(study: Path, mode: str, delay: float, hang_after: float, env: dict[str, str],
            source: Path, to_group: bool) -> dict:
    """One interrupted session: its exit code, whether it crashed, printed a traceback or hung."""
    command = [sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
               "--participant", "P01", "--scenario", "perturbed", "--auto", "--no-progress",
               "--realtime" if mode == "realtime" else "--rehearse"]
    # in the checkout run: ``-m`` puts the working folder first on sys.path, before PYTHONPATH
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=env, cwd=source, start_new_session=to_group)
    time.sleep(delay)  # the moment of the Ctrl-C, drawn by the caller
    if to_group:
        os.killpg(process.pid, signal.SIGINT)
    else:
        process.send_signal(signal.SIGINT)
    hung = False
    try:
        out, err = process.communicate(timeout=hang_after)
    except subprocess.TimeoutExpired:
        hung = True
        process.kill()
        out, err = process.communicate()
    text, rc = out + err, process.returncode
    return {"rc": rc, "hung": hung, "crashed": not hung and (rc < 0 or rc == 139),
            "traceback": any(word in text for word in CRASH_WORDS),
            # neither Ctrl-C's 130 nor a session that ended (0) before the signal came
            "other exit": not hung and rc not in (0, 128 + signal.SIGINT, 139) and rc >= 0,
            "tail": text[-1500:]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--mode", choices=("realtime", "rehearse"), default="realtime")
    parser.add_argument("--earliest", type=float, default=1.0)
    parser.add_argument("--latest", type=float, default=30.0)
    parser.add_argument("--hang-after", type=float, default=120.0)
    parser.add_argument("--hogs", type=int, default=1)
    parser.add_argument("--seed", type=int, default=44)
    parser.add_argument("--source", type=Path, help="another checkout to run (the baseline)")
    parser.add_argument("--to", choices=("group", "pid"), default="group",
                        help="the SIGINT's receiver: the process group (Ctrl-C) or the command")
    args = parser.parse_args()
    env = dict(os.environ)
    source = (args.source or Path(__file__).resolve().parents[1]).resolve()
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(source), env.get("PYTHONPATH")]))
    rng = np.random.default_rng(args.seed)
    counts: Counter[str] = Counter()
    # stopped with SIGTERM (kill, pkill), it ends its hogs too: on Python's default action they
    # outlived it
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    hogs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(args.hogs)]
    began = time.monotonic()
    try:
        for run in range(args.runs):
            delay = float(rng.uniform(args.earliest, args.latest))
            with tempfile.TemporaryDirectory(prefix="interrupted-") as folder:
                result = one_run(Path(folder) / "study", args.mode, delay, args.hang_after, env,
                                 source, args.to == "group")
            for key in KINDS:
                counts[key] += result[key]
            print(f"run {run + 1:3d}: SIGINT at {delay:5.1f} s -> rc {result['rc']}"
                  + "".join(f", {key}" for key in KINDS if result[key]), flush=True)
            if any(result[key] for key in KINDS):
                print("    " + result["tail"].replace("\n", "\n    "), flush=True)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    print(f"\n{source} ({args.mode}, {args.runs} runs, SIGINT to the {args.to} in [{args.earliest:g}, "
          f"{args.latest:g}] s, {args.hogs} CPU hog(s), {time.monotonic() - began:.0f} s): "
          f"{counts['crashed']} crashed, {counts['traceback']} printed a traceback, "
          f"{counts['hung']} hung, {counts['other exit']} ended with another exit code")
    return 0


if __name__ == "__main__":
    sys.exit(main())
