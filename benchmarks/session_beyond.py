"""Beyond the paper on the session's own simulated study (issue 40): stopping, ties and hints in
whole sessions of ``run-session --auto``'s simulated participant, both scenarios.

Every session is the real :class:`~app.protocol.engine.SessionEngine` with its learner process, the
paper's protocol (5 + 4 batches of 5, the best, the questionnaire, 4 validation pairs) and the
simulated participant of ``--auto`` (:mod:`app.protocol.simulated_participant`: a preferred arrival
gap g*, impressions with the noise of eq. (16), "equal" within ``tie_s``, hints when the felt gap
misses g* by more than ``hint_s``); each trial is the controller and the simulated hand of
``run-session`` on simulated time (``robot_io.control.trial.simulate_trial``), without the rig
process and the threads around it. The arms are configurations of the same participant (the same
taste, hands and impressions: paired by construction):

- ``paper``: the defaults (the paper's fixed schedule, ties dropped, no hints);
- ``stop``: ``stop_when_settled = true`` with its defaults;
- ``ties``: ``[learner] ties = "model"``;
- ``coactive``: ``[protocol] coactive = true``;
- ``all``: the three together.

Per session: the learning interactions used, the miss of the learned θ* (|mean arrival gap of θ*
over 8 new hands − g*|, seconds: the participant's regret), the validation score (the share of
validation pairs preferring θ*, ties dropped, as Tables II–III), the hints and ties. Printed per
arm against ``paper``: interactions used, the miss (ratio of means, paired percentile bootstrap 95 %
interval) and the validation score. Resumable: one JSON line per session under ``--out``; runs on
Dask like the other studies (``--scheduler`` for a cluster).

Usage: ``nice -n 10 .venv/bin/python benchmarks/session_beyond.py --participants 10 --workers 2``
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import dask
import numpy as np
from pydantic import BaseModel
from recommendation_study import ratio_ci

from app.learning.cluster import dask_client, run_tasks
from app.learning.rng import derive_seed
from app.protocol.auto import act_once
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario
from session_store.vocabulary import Phase

#: Each arm's configuration beyond the paper's defaults.
ARMS: dict[str, dict[str, object]] = {
    "paper": {},
    "stop": {"stop_when_settled": True},
    "ties": {"ties": "model"},
    "coactive": {"coactive": True},
    "all": {"stop_when_settled": True, "ties": "model", "coactive": True},
}
#: New hands over which the learned θ*'s arrival gap is averaged.
MISS_HANDS = 8


class SessionResult(BaseModel):
    arm: str
    scenario: Scenario
    participant: int
    seed: int
    preferred_gap_s: float
    learning_interactions: int
    miss_s: float
    wins: int
    pairs: int
    hints: int
    ties: int
    seconds: float


def session_seed(study_seed: int, scenario: Scenario, participant: int) -> int:
    return derive_seed(study_seed, list(Scenario).index(scenario), participant) % 2**32


def run_session(arm: str, scenario: Scenario, participant: int, study_seed: int) -> SessionResult:
    """One participant's whole session in arm ``arm``, headless, in a folder of its own."""
    start = time.monotonic()
    seed = session_seed(study_seed, scenario, participant)
    simulated = SimulatedParticipant(seed)
    config = StudyConfig.model_validate({"scenario": scenario, "seed": seed, **ARMS[arm]})
    with tempfile.TemporaryDirectory(prefix="session-beyond-") as folder:
        engine = SessionEngine.create(Path(folder), "P01", config)
        try:
            while engine.state.step is not Step.DONE:
                act_once(engine, simulated)
            trials = [t for t in engine.store.rows("trials") if t.outcome == "completed"]
            best = next(t for t in trials if t.phase == Phase.BEST)
            ratings = [r for r in engine.store.rows("validation_ratings")
                       if r.learned_preferred is not None]
            hints = sum(h.hint is not None for h in engine.store.rows("hints"))
            ties = sum(p.equal_to is not None for p in engine.store.rows("placements"))
        finally:
            engine.close()
    gaps = [simulate_trial(config.controller, best.theta, scenario,
                           derive_seed(seed, 0x6A9, hand) % 2**31).summary.arrival_gap_s
            for hand in range(MISS_HANDS)]
    miss = abs(float(np.mean([g for g in gaps if g is not None])) - simulated.taste.preferred_gap_s)
    return SessionResult(
        arm=arm, scenario=scenario, participant=participant, seed=seed,
        preferred_gap_s=simulated.taste.preferred_gap_s,
        learning_interactions=sum(t.phase in (Phase.INITIAL, Phase.LEARNING) for t in trials),
        miss_s=miss, wins=sum(bool(r.learned_preferred) for r in ratings), pairs=len(ratings),
        hints=hints, ties=ties, seconds=time.monotonic() - start)


def lines(results: dict[str, list[SessionResult]], seed: int) -> list[str]:
    """One line per arm against the paper's: interactions used, miss, validation score."""
    paper = results["paper"]
    base_used = np.array([r.learning_interactions for r in paper], dtype=float)
    base_miss = np.array([r.miss_s for r in paper])
    out = []
    for arm, rs in results.items():
        used = np.array([r.learning_interactions for r in rs], dtype=float)
        miss = np.array([r.miss_s for r in rs])
        saving, lo_s, hi_s = ratio_ci(used, base_used, seed)
        ratio, lo, hi = ratio_ci(miss + 1e-9, base_miss + 1e-9, seed)
        wins, pairs = sum(r.wins for r in rs), sum(r.pairs for r in rs)
        out.append(
            f"session {arm}: interactions median {np.median(used):g} (mean {used.mean():.1f}, "
            f"{1 - saving:.0%} fewer [{1 - hi_s:.0%}, {1 - lo_s:.0%}]); miss of θ* "
            f"{miss.mean() * 1000:.0f} ms vs paper {base_miss.mean() * 1000:.0f} ms, ratio "
            f"{ratio:.3f} [{lo:.3f}, {hi:.3f}]; validation: θ* preferred in {wins} of {pairs} "
            f"pairs ({wins / max(pairs, 1):.0%}); hints per session {np.mean([r.hints for r in rs]):.1f}, "
            f"ties {np.mean([r.ties for r in rs]):.1f}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=10, help="per scenario")
    parser.add_argument("--seed", type=int, default=4041)
    parser.add_argument("--arms", nargs="+", default=list(ARMS), choices=list(ARMS))
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/session-beyond"))
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()

    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"sessions-seed{args.seed}.jsonl"
    done: dict[tuple[str, Scenario, int], SessionResult] = {}
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                r = SessionResult.model_validate_json(line)
                done[(r.arm, r.scenario, r.participant)] = r

    def finished(result: SessionResult) -> None:
        with path.open("a") as handle:
            handle.write(result.model_dump_json() + "\n")
        done[(result.arm, result.scenario, result.participant)] = result

    wanted = [(arm, scenario, p) for p in range(args.participants) for scenario in Scenario
              for arm in args.arms]
    todo = [(*key, args.seed) for key in wanted if key not in done]
    start = time.monotonic()
    # a session starts its learner in a process of its own: Dask's workers must not be daemons
    # (on a lab's cluster, start them with --no-nanny or the same setting)
    with dask.config.set({"distributed.worker.daemon": False}), \
            dask_client(args.scheduler, args.workers) as client:
        run_tasks(client, run_session, todo, finished, total=len(wanted),
                  initial=len(wanted) - len(todo), desc="sessions", progress=not args.no_progress)
    wall = time.monotonic() - start
    results = {arm: [done[(arm, s, p)] for p in range(args.participants) for s in Scenario]
               for arm in args.arms}
    print(f"N = {args.participants} participants per scenario ({2 * args.participants} paired), "
          f"seed {args.seed}; {np.median([r.seconds for r in done.values()]):.0f} s per session "
          f"(median) in a worker, {wall:.0f} s wall for this run")
    for line in lines(results, args.seed):
        print(line)
    print("baseline (the paper's session): " + json.dumps(
        {"miss_ms": round(1000 * float(np.mean([r.miss_s for r in results["paper"]])), 1),
         "interactions": float(np.mean([r.learning_interactions for r in results["paper"]]))}))


if __name__ == "__main__":
    main()
