"""``handover simulate-trial`` (one handover of the simulated hand with the mock arm or a UR),
``handover check-devices`` and ``handover calibrate-tracker``: the commands on the rig's devices. They
live in the application, which reads the lab configuration (``app.session.config``); ``robot_io``
below it never imports the application."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from app.arguments import argument_type
from app.session.config import load_lab_config
from robot_io.arms.kinds import ARMS
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import Theta

#: Summary fields printed by --json, in order.
JSON_FIELDS = (
    "outcome", "reason", "robot_arrival_s", "hand_arrival_s", "arrival_gap_s", "peak_speed_mps",
    "max_tau", "deadline_misses", "cycles", "duration_s", "rate_hz", "realtime", "limited_cycles",
    "invalid_hand_samples", "compute_us_median", "compute_us_p99",
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "simulate-trial", help="run one handover with the simulated hand and the mock arm",
        description="Run one handover of the simulated participant with the kinematic mock arm.")
    parser.add_argument("--scenario", required=True, type=argument_type(Scenario.parse),
                        choices=list(Scenario),
                        help="straightforward or perturbed (Sect. V-A)")
    parser.add_argument("--theta", required=True, type=argument_type(Theta.parse), metavar="A,DELTA,K",
                        help="coupling θ = (a, δ, k); a in [1, 10], δ in [-1, 1], k in [0.01, 15]")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated hand")
    parser.add_argument("--rate", type=int, choices=(125, 500), help="control rate [Hz]")
    parser.add_argument("--realtime", action="store_true",
                        help="run on the wall clock (default: simulated time, as fast as possible)")
    parser.add_argument("--config", type=Path, help="the lab configuration file (TOML, docs/hardware.md)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", type=Path, metavar="FILE.png",
                        help="write the Fig. 4 style distance plot")
    parser.add_argument("--arm", choices=tuple(ARMS),
                        help="[arm] kind (robot_io.arms.kinds); mock: the kinematic mock arm; ur: a UR "
                             "over RTDE (real time, moves it!); default: [arm] kind of the config")
    parser.add_argument("--ur-host", help="UR controller address (default: [ur] host of the config); "
                             "implies [arm] kind = ur")
    parser.add_argument("--samples", type=Path, metavar="FILE.npz", help="write the per-cycle samples")
    parser.set_defaults(func=run)

    check = subparsers.add_parser(
        "check-devices", help="connect to the configured arm, hand source and gripper; move nothing",
        description="Connect to the configured UR arm, hand source and gripper and report versions, "
                    "rates and faults in plain words. Nothing moves and no output is switched.")
    check.add_argument("--config", type=Path, help="the lab configuration file (TOML, docs/hardware.md)")
    check.add_argument("--ur-host", help="UR controller address (default: [ur] host of the config); "
                             "implies [arm] kind = ur")
    check.set_defaults(func=run_check_devices)

    calibrate = subparsers.add_parser(
        "calibrate-tracker", help="fit the tracker → robot base transform from point pairs",
        description="Fit the rigid transform from tracker to robot base coordinates (Kabsch) from a CSV "
                    "of point pairs: tx,ty,tz (tracker units) and bx,by,bz (robot base, m), one pair "
                    "per line, N ≥ 3 not on one line. Prints the [hand_source] TOML lines and the RMS "
                    "residual. See docs/hardware.md.")
    calibrate.add_argument("pairs", type=Path, help="CSV file: tx,ty,tz,bx,by,bz per line")
    calibrate.add_argument("--config", type=Path, help="TOML configuration file (for units_to_m)")
    calibrate.set_defaults(func=run_calibrate_tracker)


def load_config(path: Path | None):
    """The controller part of the lab configuration file (``--config lab.toml``, one file for every
    command: the whole file is validated, its [protocol] and [learner] tables included)."""
    return load_lab_config(path).controller


def run_calibrate_tracker(args: argparse.Namespace) -> int:
    from robot_io.hands.frame import fit_kabsch

    units = load_config(args.config).hand_source.units_to_m
    try:
        pairs = np.loadtxt(args.pairs, delimiter=",", ndmin=2, comments="#")
    except (OSError, ValueError) as exc:
        raise ValueError(f"pairs file {args.pairs}: {exc}") from exc
    if pairs.shape[1] != 6:
        raise ValueError(f"pairs file {args.pairs}: {pairs.shape[1]} columns, expected 6 (tx,ty,tz,bx,by,bz)")
    transform, residual = fit_kabsch(pairs[:, :3] * units, pairs[:, 3:])
    rows = ", ".join("[" + ", ".join(f"{v:.6f}" for v in row) + "]" for row in transform.rotation)
    print("[hand_source]")
    print(f"rotation = [{rows}]")
    print("translation = [" + ", ".join(f"{v:.5f}" for v in transform.translation) + "]")
    print(f"units_to_m = {units:g}")
    print(f"# {len(pairs)} pairs, RMS residual {1e3 * residual:.2f} mm")
    return 0


def _with_host(config, host: str | None, arm: str | None = None):
    """``--ur-host`` names a UR controller: it sets [ur] host and [arm] kind = "ur"; ``--arm``
    sets [arm] kind. Validated again as the file is: ``--arm ur`` without a host is refused,
    naming the key, before anything connects."""
    if host is None and arm is None:
        return config
    tables = config.model_dump()
    if host is not None:
        tables["ur"]["host"], tables["arm"]["kind"] = host, "ur"
    if arm is not None:
        tables["arm"]["kind"] = arm
    return type(config).model_validate(tables)


def run_check_devices(args: argparse.Namespace) -> int:
    from robot_io.devices import check_devices

    lines, ok = check_devices(_with_host(load_config(args.config), args.ur_host))
    print("\n".join(lines))
    return 0 if ok else 1


def _run_on_arm(config, args: argparse.Namespace):
    from robot_io.devices import arm_trial
    from robot_io.hands.simulated_hand import SimulatedHand

    arm = config.arm.connect(config)
    try:
        if args.rate is not None and args.rate != arm.rate_hz:
            raise ValueError(f"--rate = {args.rate} but the arm ({arm.describe()}) runs at "
                             f"{arm.rate_hz} Hz")
        hand = SimulatedHand(args.scenario, config.scene, config.hand, args.seed)
        return arm_trial(config, args.theta, hand, arm)
    finally:
        arm.close()


def run(args: argparse.Namespace) -> int:
    from robot_io.control.trial import simulate_trial
    from robot_io.plot import plot_trial

    config = _with_host(load_config(args.config), args.ur_host, args.arm)
    if args.rate is not None:
        config = config.model_copy(
            update={"loop": config.loop.model_copy(update={"rate_hz": args.rate})})
    if not config.arm.simulated:
        record = _run_on_arm(config, args)
    else:
        record = simulate_trial(config, args.theta, args.scenario, args.seed, realtime=args.realtime)
    summary = record.summary
    if args.samples:
        np.savez(args.samples, **record.samples)
    if args.plot:
        theta = args.theta
        plot_trial(record.samples, config.scene.point("handover_point"), args.plot,
                   title=f"{args.scenario.value}, a={theta.a:g} δ={theta.delta:g} k={theta.k:g}, "
                         f"seed {args.seed}")
    if args.json:
        data = summary.model_dump(mode="json", include=set(JSON_FIELDS))
        data.update(scenario=args.scenario.value, theta=args.theta.model_dump(), seed=args.seed)
        print(json.dumps(data))
    else:
        def seconds(value: float | None, sign: str = "") -> str:
            return "n/a" if value is None else f"{value:{sign}.3f} s"

        print(f"{summary.outcome.value}: robot at H {seconds(summary.robot_arrival_s)}, hand at H "
              f"{seconds(summary.hand_arrival_s)}, gap {seconds(summary.arrival_gap_s, '+')}, "
              f"peak speed {summary.peak_speed_mps:.2f} m/s, "
              f"max τ {summary.max_tau:.2f} s, {summary.deadline_misses} deadline misses"
              + (f" ({summary.reason})" if summary.reason else ""))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0 if summary.outcome == "completed" else 1
