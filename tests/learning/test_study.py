"""The simulated study: eq. (16) trials, resumable CSV, CLI contract, and qNEI vs Sobol."""

from __future__ import annotations

import csv
import json
import math
import warnings

import numpy as np
import pytest
from scipy import stats

from app.cli import main
from app.learning.config import AcquisitionName
from app.learning.errors import StudyError
from app.learning.models import RecommendationName
from app.learning.simulated_study import (
    TRIAL_COLUMNS,
    TrialStore,
    final_distances,
    run_condition,
    summarise,
    t_half_width,
)
from app.learning.simulation import SUCCESS_DISTANCE, StudyCondition, TrialResult, run_trial

SMALL = StudyCondition(acquisition=AcquisitionName.QNEI, q=2, noise=0.05, n_unique=7,
                       n_initial=3, recommendation=RecommendationName.IN_SAMPLE_MEAN)


def test_a_trial_follows_the_schedule_and_reports_theta_star_distances():
    result = run_trial(SMALL, seed=3, trial=0)
    n = SMALL.schedule.n_interactions
    assert len(result.distances) == len(result.shown_distances) == n
    assert all(0.0 <= d <= math.sqrt(3) for d in result.distances)
    # θ* is always one of the points shown so far
    for i, d in enumerate(result.distances):
        assert min(abs(d - s) for s in result.shown_distances[: i + 1]) < 1e-12
    assert run_trial(SMALL, seed=3, trial=0).distances == result.distances
    # the oracle curve is the best point shown so far; θ* can never beat it
    assert result.oracle_distances == [min(result.shown_distances[: i + 1]) for i in range(n)]
    assert all(d >= o for d, o in zip(result.distances, result.oracle_distances, strict=True))
    # every strategy's final recommendation is recorded, the untracked ones only there
    finals = {s: c[-1] for s, c in result.strategy_distances.items()}
    assert finals[RecommendationName.IN_SAMPLE_MEAN] == result.distances[-1]
    assert all(0.0 <= d <= math.sqrt(3) for d in finals.values())
    assert math.isnan(result.strategy_distances[RecommendationName.IN_SAMPLE_LCB][0])


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
    results = [TrialResult(trial=t, distances=[0.5, d], shown_distances=[0.4, d],
                           fit_failures=0, seconds=1.0) for t, d in enumerate([0.05, 0.2, 0.08])]
    first, last = summarise(results)
    assert first.mean_distance == pytest.approx(0.5) and first.ci_low == pytest.approx(0.5)
    assert last.mean_distance == pytest.approx(0.11)
    assert last.ci_low < last.mean_distance < last.ci_high
    assert last.success_rate == pytest.approx(2 / 3)  # u < 0.1 for 0.05 and 0.08
    assert first.mean_oracle_distance == pytest.approx(0.4)
    assert last.mean_oracle_distance == pytest.approx(0.11)  # each below 0.4: the new point
    assert SUCCESS_DISTANCE == 0.1


def test_an_interrupted_run_resumes_from_the_completed_trials(tmp_path, client):
    """Slow (~26 s in a loaded full run): four simulated-study trials, each a run of the real
    learner: two, then the interrupted third on the Dask cluster, and the third once more in the
    test process to compare."""
    run_condition(SMALL, trials=2, seed=9, client=client, out=tmp_path, progress=False)
    path = tmp_path / SMALL.name / "trials.csv"
    done = path.read_text()
    # an interruption in the middle of trial 2's rows: a partial trial and a torn line
    with path.open("a") as handle:
        handle.write("2,1,0.5,0.5,0.5,0.5,0.5,0.5,0\n2,2,0.4")
    summary, rows = run_condition(SMALL, trials=3, seed=9, client=client, out=tmp_path, progress=False)
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(TRIAL_COLUMNS)
    assert path.read_text().startswith(done)  # trials 0 and 1 kept byte for byte: not rerun
    n = SMALL.schedule.n_interactions
    assert len(lines) == 1 + 3 * n and summary.trials == 3 and rows[0].n_trials == 3
    rerun = [float(line.split(",")[2]) for line in lines[1 + 2 * n:]]
    assert rerun == pytest.approx(run_trial(SMALL, seed=9, trial=2).distances)


def test_resuming_with_another_seed_is_refused(tmp_path, client):
    run_condition(SMALL, trials=1, seed=1, client=client, out=tmp_path, progress=False)
    with pytest.raises(StudyError, match="seed = 1"):
        run_condition(SMALL, trials=1, seed=2, client=client, out=tmp_path, progress=False)


def test_cli_json_summary(tmp_path, capsys, on_the_cluster):
    code = main(["benchmark-pl", "--acq", "eubo", "--q", "2", "--noise", "0.05", "--trials", "2",
                 "--queries", "6", "--initial", "3", "--seed", "4", "--out", str(tmp_path),
                 "--json", "--no-progress", *on_the_cluster])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["trials"] == 2 and summary["interactions"] == 3 + 2 * 3
    for key in ("final_mean_distance", "final_success_rate", "seconds_per_trial"):
        assert summary[key] >= 0.0
    assert (tmp_path / "eubo-q2-s0.05" / "summary.csv").exists()


def test_cli_batch_position_noise_is_its_own_condition(tmp_path, capsys, on_the_cluster):
    """--batch-position-noise runs the same trials with the likelihood of eq. (16) into their own
    folder (a resumed run never mixes the two likelihoods)."""
    args = ["benchmark-pl", "--q", "3", "--noise", "0.05", "--trials", "1", "--queries", "7",
            "--initial", "3", "--seed", "4", "--out", str(tmp_path), "--json", "--no-progress",
            *on_the_cluster]
    summaries = []
    for extra in ([], ["--batch-position-noise"]):
        assert main([*args, *extra]) == 0
        summaries.append(json.loads(capsys.readouterr().out))
    equal, weighed = summaries
    assert (equal["condition"], weighed["condition"]) == ("qnei-q3-s0.05", "qnei-q3-s0.05-bpn")
    trials = [(tmp_path / name / "trials.csv").read_text() for name in
              ("qnei-q3-s0.05", "qnei-q3-s0.05-bpn")]
    assert trials[0] != trials[1]


def test_cli_coactive_is_its_own_condition_and_counts_the_hints(tmp_path, capsys, on_the_cluster):
    """--coactive runs the same trials with a participant who hints, into their own folder; the
    hints of each trial are in trials.csv and their mean in the summary."""
    args = ["benchmark-pl", "--q", "3", "--noise", "0.05", "--trials", "2", "--queries", "5",
            "--initial", "3", "--seed", "4", "--out", str(tmp_path), "--json", "--no-progress",
            *on_the_cluster, "--coactive"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["condition"] == "qnei-q3-s0.05-coactive0.2"
    with (tmp_path / summary["condition"] / "trials.csv").open() as handle:
        hints = {int(r["trial"]): int(r["hints"]) for r in csv.DictReader(handle)}
    assert sum(hints.values()) > 0
    assert summary["hints_per_trial"] == pytest.approx(sum(hints.values()) / 2)
    assert main([*args[:-1]]) == 0  # without hints: another folder, no hints counted
    assert json.loads(capsys.readouterr().out)["hints_per_trial"] == 0


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


def test_a_paired_study_gives_every_condition_the_same_targets_and_initial_design(tmp_path, client):
    """The code path of the positive control (benchmarks/learner_beats_sobol.py: qNEI and EUBO
    against Sobol, issue 14's goals, a study of 16 trials per condition that left the suite) on a
    small fixed-seed study: each condition runs and resumes from its CSV under the same study seed,
    so trial t of every condition has the same target, noise and initial Sobol design; only the
    learned queries differ."""
    stored, finals = {}, {}
    for acquisition in (AcquisitionName.QNEI, AcquisitionName.SOBOL):
        condition = StudyCondition(acquisition=acquisition, q=5, noise=0.03, n_unique=7, n_initial=3)
        finals[acquisition] = final_distances(condition, trials=2, seed=7, client=client, out=tmp_path)
        stored[acquisition] = TrialStore(tmp_path / condition.name, condition, 7).load()
        assert final_distances(condition, trials=2, seed=7, client=client,
                               out=tmp_path) == finals[acquisition]  # read back from the CSV
    learned, sobol = stored[AcquisitionName.QNEI], stored[AcquisitionName.SOBOL]
    for t in range(2):
        assert learned[t].shown_distances[:3] == sobol[t].shown_distances[:3]  # same design
        assert learned[t].shown_distances != sobol[t].shown_distances  # the queries differ
        assert finals[AcquisitionName.QNEI][t] == learned[t].distances[-1]
    diff = np.subtract(finals[AcquisitionName.QNEI], finals[AcquisitionName.SOBOL])
    assert t_half_width(list(diff)) == pytest.approx(stats.t.ppf(0.975, 1) * abs(diff[0] - diff[1]) / 2)


def test_two_dask_workers_write_the_same_csv_as_one(tmp_path, on_the_cluster):
    """Trials are seeded by (seed, trial) alone and the file is rewritten in trial order, so the
    worker count changes nothing, nor does the cluster (the shared one-worker cluster's scheduler,
    and the command's own LocalCluster of two); seconds go to timings.csv, apart from the results."""
    files = {}
    for workers, cluster in ((1, on_the_cluster), (2, ["--workers", "2"])):
        out = tmp_path / f"w{workers}"
        assert main(["benchmark-pl", "--acq", "qnei", "--q", "2", "--noise", "0.05", "--trials",
                     "3", "--queries", "5", "--initial", "3", "--seed", "11", *cluster,
                     "--out", str(out), "--no-progress", "--json"]) == 0
        files[workers] = (out / "qnei-q2-s0.05" / "trials.csv").read_text()
        timings = (out / "qnei-q2-s0.05" / "timings.csv").read_text().splitlines()
        assert timings[0] == "trial,seconds" and len(timings) == 4
    assert files[1] == files[2]
    assert len(files[1].splitlines()) == 1 + 3 * SMALL.model_copy(
        update={"n_unique": 5}).schedule.n_interactions


def test_every_failed_fit_is_counted_including_those_run_before_a_query(monkeypatch):
    """The study preset fits lazily, just before a query (not in observe); a trial's
    fit_failures counts every hyperparameter fit that failed, wherever it ran. BoTorch's fit is
    made to fail on every call after the first; the count must equal the failures it raised."""
    from botorch.exceptions import ModelFittingError

    from app.learning import preference_model

    real, calls, raised = preference_model.fit_gpytorch_mll, [], []

    def fails_after_the_first(*args, **kwargs):
        calls.append(1)
        if len(calls) > 1:
            raised.append(1)
            raise ModelFittingError("injected")
        return real(*args, **kwargs)

    monkeypatch.setattr(preference_model, "fit_gpytorch_mll", fails_after_the_first)
    assert SMALL.model.lazy_fit  # the preset whose fits run in suggest
    result = run_trial(SMALL, seed=3, trial=0)
    assert len(raised) >= 2
    assert result.fit_failures == len(raised)
