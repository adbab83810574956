"""The lab configuration file: one pydantic model for every command, its [protocol] and [learner]
tables reaching new sessions, and bad input named with its field and range."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from app.cli import main
from app.session.config import LabConfig, load_lab_config
from robot_io.simulated_hand import Scenario


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
"""))
    study = lab.study_config(Scenario.PERTURBED, seed=9)
    assert (study.batch_size, study.learning_batches, study.acquisition) == (3, 2, "eubo")
    assert study.initial_trials == 5  # the paper's default where the file says nothing
    assert study.controller.arm.kind == "ur" and study.controller.ur.host == "127.0.0.7"
    assert study.controller.hand_source.lsl_stream_name == "Vicon hand"


@pytest.mark.parametrize(("text", "message"), [
    ("[protocl]\nbatch_size = 3\n", "protocl"),
    ("[protocol]\nbatch_size = 30\n", "protocol.batch_size"),
    ("[arm]\nkind = \"ur5\"\n", "arm.kind"),
    ("[cycle]\nstart_zone_m = 2.0\n", "cycle.start_zone_m"),
])
def test_a_bad_file_is_refused_naming_the_field(tmp_path, text, message):
    with pytest.raises(ValidationError, match=message):
        load_lab_config(write(tmp_path, text))


def test_every_command_reads_the_same_file_and_refuses_it_before_writing(tmp_path, capsys):
    path = write(tmp_path, "[protocol]\nbatch_size = 30\n")
    study = tmp_path / "study"
    for command in (["run-session", "--study", str(study), "--participant", "P1", "--scenario",
                     "perturbed", "--auto"], ["simulate-trial", "--scenario", "perturbed",
                                              "--theta", "5,-0.2,5"], ["check-devices"]):
        assert main([*command, "--config", str(path)]) == 2
        assert "protocol.batch_size = 30" in capsys.readouterr().err
    assert not study.exists()


def test_serve_takes_no_protocol_file_any_more(capsys):
    with pytest.raises(SystemExit):
        main(["serve", "--protocol", "short.toml"])
    assert "unrecognized arguments: --protocol" in capsys.readouterr().err


def test_the_controller_part_is_what_the_rig_gets():
    lab = LabConfig.model_validate({"protocol": {"batch_size": 4}, "loop": {"rate_hz": 125}})
    controller = lab.controller
    assert controller.loop.rate_hz == 125 and not hasattr(controller, "protocol")
