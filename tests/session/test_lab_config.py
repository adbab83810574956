"""The lab configuration file: one pydantic model for every command, its [protocol] and [learner]
tables reaching new sessions, and bad input named with its field and range."""

from __future__ import annotations

from typing import get_args

import pytest
from pydantic import ValidationError
from support.engine import new_engine

from app.cli import main
from app.learning.config import AcquisitionName
from app.protocol.session_inputs import learner_config
from app.protocol.study_config import StudyConfig
from app.session.config import LabConfig, load_lab_config
from robot_io.hands.simulated_hand import Scenario


def write(tmp_path, text: str):
    path = tmp_path / "lab.toml"
    path.write_text(text)
    return path


def test_one_file_configures_the_rig_the_protocol_and_the_learner(tmp_path):
    lab = load_lab_config(write(tmp_path, """
[arm]
kind = "ur"
[ur]
host = "127.0.0.7"
[hand_source]
kind = "lsl"
lsl_stream_name = "Vicon hand"
[gripper]
kind = "tool_output"
[protocol]
batch_size = 3
learning_batches = 2
[learner]
acquisition = "eubo"
recommendation = "posterior_mean"
population_prior = true
prior_weight = 0.5
batch_position_noise = true
"""))
    study = lab.study_config(Scenario.PERTURBED, seed=9)
    assert (study.batch_size, study.learning_batches, study.acquisition) == (3, 2, "eubo")
    assert (study.recommendation, study.population_prior, study.prior_weight) == (
        "posterior_mean", True, 0.5)
    assert learner_config(study).model.batch_position_noise  # the learner weighs by eq. (16)
    assert not learner_config(lab.study_config(Scenario.PERTURBED, seed=9).model_copy(
        update={"batch_position_noise": False})).model.batch_position_noise
    assert study.prior_sources == []  # filled when the session is created, never by the lab
    assert study.initial_trials == 5  # the paper's default where the file says nothing
    assert study.controller.arm.kind == "ur" and study.controller.ur.host == "127.0.0.7"
    assert study.controller.hand_source.lsl_stream_name == "Vicon hand"


@pytest.mark.parametrize(("text", "message"), [
    ("[protocl]\nbatch_size = 3\n", "protocl"),
    ("[protocol]\nbatch_size = 30\n", "protocol.batch_size"),
    ("[arm]\nkind = \"ur5\"\n", r"\[arm\] kind = 'ur5' is no arm; the kinds are \"mock\", \"ur\""),
    ("[cycle]\nstart_zone_m = 2.0\n", "cycle.start_zone_m"),
    ("[learner]\nrecommendation = \"best\"\n", "learner.recommendation"),
    ("[learner]\nacquisition = \"sobol\"\n",
     r"learner.acquisition\n.*Input should be 'qnei', 'qlognei' or 'eubo'"),
    ("[learner]\nprior_weight = 11\n", "learner.prior_weight"),
    ("[learner]\nbatch_position_noise = \"maybe\"\n", "learner.batch_position_noise"),
    ("[learner]\nprior_sources = [\"P01\"]\n", "prior_sources"),
    ("[record]\nlsl_name = \"my streams!\"\n", r"record.lsl_name\n.*must be 1 to 64 letters"),
    ("[record]\nlsl_outlet = true\n", "record.lsl_outlet"),
])
def test_a_bad_file_is_refused_naming_the_field(tmp_path, text, message):
    with pytest.raises(ValidationError, match=message):
        load_lab_config(write(tmp_path, text))


def refused_by_every_command(tmp_path, capsys, text: str, message: str) -> None:
    """Each command that reads a lab config exits 2 on ``text``, says ``message``, and writes no
    study folder."""
    path = write(tmp_path, text)
    study = tmp_path / "study"
    for command in (["run-session", "--study", str(study), "--participant", "P1", "--scenario",
                     "perturbed", "--auto"], ["simulate-trial", "--scenario", "perturbed",
                                              "--theta", "5,-0.2,5"], ["check-devices"]):
        assert main([*command, "--config", str(path)]) == 2
        assert message in capsys.readouterr().err
    assert not study.exists()


def test_every_command_reads_the_same_file_and_refuses_it_before_writing(tmp_path, capsys):
    refused_by_every_command(tmp_path, capsys, "[protocol]\nbatch_size = 30\n",
                             "protocol.batch_size = 30")


@pytest.mark.parametrize(("text", "message"), [
    ("[arm]\nkind = \"ur\"\n", '[ur] host is not set; [arm] kind = "ur" needs the UR'),
    ("[arm]\nkind = \"ur\"\n[gripper]\nkind = \"tool_output\"\n", "[ur] host is not set"),
    ("[gripper]\nkind = \"tool_output\"\n", "gripper.kind = 'tool_output' needs arm.kind = 'ur'"),
])
def test_a_ur_without_a_host_is_refused_never_assumed(tmp_path, capsys, text, message):
    """A device's address has no default: a UR (or its tool output) with no [ur] host is refused by
    every command, naming the key, before anything is written or any address is tried (before, it
    drove 192.168.1.10, where a lab's network may have another robot); so is a tool output without
    the UR it belongs to (before, only once the rig process had started)."""
    refused_by_every_command(tmp_path, capsys, text, message)
    assert LabConfig().ur.host is None


@pytest.mark.parametrize(("text", "message"), [
    ("[protocol]\nlearning_batches = 0\n",
     "learning_batches = 0 runs sessions that never learn θ (no learning batch): set "
     "learning_batches in [1, 50], or without_learning = true"),
    ("[protocol]\nwithout_learning = true\n",
     "without_learning = true contradicts learning_batches = 4"),
])
def test_a_protocol_that_cannot_learn_is_refused_unless_the_lab_says_so(tmp_path, capsys, text,
                                                                        message):
    """``learning_batches = 0`` ran a "study" that never learned θ, with no word (issue 25, item
    10): every command refuses it, naming the key that allows it; said explicitly, it runs."""
    refused_by_every_command(tmp_path, capsys, text, message)
    lab = load_lab_config(write(tmp_path, "[protocol]\nlearning_batches = 0\nwithout_learning = true\n"))
    study = lab.study_config(Scenario.PERTURBED, seed=9)
    assert study.learning_batches == 0 and study.interactions == 5 + 1 + 8


def test_resuming_with_a_bad_device_table_writes_not_even_the_lock_file(tmp_path, capsys):
    """An existing participant's writer lock was taken (its file rewritten with the holder) before
    the lab file was read; a [arm] kind = "ur" without [ur] host then refused the command after
    that write (issue 25, item 2). Now the lab file is judged first."""
    study = tmp_path / "study"
    new_engine(study, "P1").close()
    lock = study / "P1.sqlite.lock"
    before = (lock.read_bytes(), lock.stat().st_mtime_ns)
    bad = write(tmp_path, '[arm]\nkind = "ur"\n')
    assert main(["run-session", "--study", str(study), "--participant", "P1", "--resume", "--auto",
                 "--config", str(bad)]) == 2
    assert "[ur] host is not set" in capsys.readouterr().err
    assert (lock.read_bytes(), lock.stat().st_mtime_ns) == before


def test_serve_takes_no_protocol_file_any_more(capsys):
    with pytest.raises(SystemExit):
        main(["serve", "--protocol", "short.toml"])
    assert "unrecognized arguments: --protocol" in capsys.readouterr().err


def test_the_controller_part_is_what_the_rig_gets():
    lab = LabConfig.model_validate({"protocol": {"batch_size": 4}, "loop": {"rate_hz": 125}})
    controller = lab.controller
    assert controller.loop.rate_hz == 125 and not hasattr(controller, "protocol")
    assert not hasattr(controller, "record")


@pytest.mark.parametrize(("text", "message"), [
    ("[protocol]\nbatch_size = inf\n", "protocol.batch_size = inf: must be a whole number in [2, 10]"),
    ("[protocol]\ninitial_trials = 2.5\n",
     "protocol.initial_trials = 2.5: must be a whole number in [2, 50]"),
    ("[protocol]\nvalidation_batches = -1\n",
     "protocol.validation_batches = -1: must be a whole number in [0, 20]"),
    ("[protocol]\nseed = 7\n", "protocol.seed = 7: Extra inputs are not permitted"),
    ("[protocol.controller.safety]\nmax_speed = 1.4\n", "protocol.controller = "),
    ("[learner.controller.loop]\nstaleness_limit_s = 0.4\n", "learner.controller = "),
    ("[learner]\ntheta_bounds = {a = [1, 10], delta = [-1, 1], k = [0.01, 40]}\n",
     "theta_bounds.k = [0.01, 40.0] must lie within the safe range [0.01, 15.0]"),
])
def test_protocol_and_learner_tables_cannot_reach_safety_and_name_the_range(tmp_path, capsys, text,
                                                                           message):
    """[protocol] and [learner] hold the study's counts and the θ box only: a controller table or
    a seed inside them is refused, and every bad value names its field and range, before anything
    is written."""
    study = tmp_path / "study"
    command = ["run-session", "--study", str(study), "--participant", "P1", "--scenario",
               "perturbed", "--auto", "--config", str(write(tmp_path, text))]
    assert main(command) == 2
    assert message in capsys.readouterr().err
    assert not study.exists()


def test_the_sessions_default_recommendation_is_the_learners():
    from app.learning.config import DEFAULT_RECOMMENDATION
    from app.learning.models import RecommendationName

    study = LabConfig().study_config(Scenario.STRAIGHTFORWARD, seed=1)
    assert study.recommendation == DEFAULT_RECOMMENDATION.value
    assert StudyConfig.model_fields["recommendation"].annotation is RecommendationName


def test_a_config_that_is_not_a_small_regular_file_is_refused_naming_the_limit(tmp_path, capsys):
    """``--config /dev/zero`` grew a command to 3.5 GB in 6 s: what is read is bounded."""
    huge = write(tmp_path, "# " + "x" * 1_100_000 + "\n")  # valid TOML, but no lab.toml is this large
    assert main(["check-devices", "--config", str(huge)]) == 2
    assert "larger than 1,000 kB, the most a lab configuration may have" in capsys.readouterr().err
    for device in ("/dev/zero", str(tmp_path)):
        assert main(["check-devices", "--config", device]) == 2
        assert f"config file {device}: not a regular file" in capsys.readouterr().err


def test_a_session_runs_the_learner_s_own_acquisitions_but_sobol():
    """The study's acquisition is the learner's type (app.learning.config.SessionAcquisition): the
    names a lab file may write are the learner's, but its random search."""
    allowed = get_args(StudyConfig.model_fields["acquisition"].annotation)
    assert all(isinstance(name, AcquisitionName) for name in allowed)
    assert set(allowed) == set(AcquisitionName) - {AcquisitionName.SOBOL}
