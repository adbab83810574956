"""``handover simulate-trial`` as a user runs it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from app.cli import main


def test_json_output_has_the_documented_fields_and_consistent_numbers(capsys):
    code = main(["simulate-trial", "--scenario", "perturbed", "--theta", "5,-0.2,15", "--seed", "1",
                 "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["outcome"] == "completed"
    for field in ("robot_arrival_s", "hand_arrival_s", "arrival_gap_s", "peak_speed_mps", "max_tau",
                  "deadline_misses"):
        assert isinstance(data[field], (int, float)), field
    assert data["arrival_gap_s"] == pytest.approx(data["robot_arrival_s"] - data["hand_arrival_s"])
    assert data["theta"] == {"a": 5.0, "delta": -0.2, "k": 15.0}
    assert 1.0 < data["max_tau"] <= 16.0 and data["peak_speed_mps"] <= 1.0


def test_rate_option_and_plot_file(tmp_path, capsys):
    plot = tmp_path / "fig4.png"
    code = main(["simulate-trial", "--scenario", "straightforward", "--theta", "1,0,0.01",
                 "--rate", "125", "--json", "--plot", str(plot)])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["rate_hz"] == 125
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and plot.stat().st_size > 10_000


def test_config_file_overrides_defaults(tmp_path, capsys):
    config = tmp_path / "lab.toml"
    config.write_text("[loop]\ntimeout_s = 0.4\n")
    code = main(["simulate-trial", "--scenario", "perturbed", "--theta", "5,0,1", "--json",
                 "--config", str(config)])
    assert code == 1 and json.loads(capsys.readouterr().out)["outcome"] == "timeout"


@pytest.mark.parametrize("args,message", [
    (["--theta", "11,0,1"], "theta.a = 11.0 is outside the allowed range [1.0, 10.0]"),
    (["--theta", "5,0,0"], "theta.k = 0.0 is outside the allowed range [0.01, 15.0]"),
    (["--theta", "5,0"], "must be three numbers"),
    (["--theta", "5,0,1", "--scenario", "sideways"], "scenario = 'sideways' is not one of"),
    (["--theta", "5,0,1", "--rate", "250"], "invalid choice: 250"),
])
def test_bad_input_exits_2_with_a_message_naming_field_and_range(args, message, capsys):
    argv = ["simulate-trial", "--scenario", "straightforward", *args]
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert message in capsys.readouterr().err


def test_bad_config_file_is_reported_not_raised(tmp_path, capsys):
    config = tmp_path / "lab.toml"
    config.write_text("[safety]\nmax_speed = -1\n")
    code = main(["simulate-trial", "--scenario", "perturbed", "--theta", "5,0,1",
                 "--config", str(config)])
    assert code == 2 and "max_speed" in capsys.readouterr().err


def test_a_ur_without_a_host_on_the_command_line_is_refused_naming_the_key(capsys):
    """``--arm ur`` with no config once reached ur_rtde with host None (a TypeError traceback)."""
    code = main(["simulate-trial", "--scenario", "perturbed", "--theta", "5,0,1", "--arm", "ur"])
    assert code == 2
    assert "[ur] host is not set" in capsys.readouterr().err


def test_console_script_is_installed():
    """The ``handover`` entry point of pyproject runs (the README's demo command uses it)."""
    out = subprocess.run([sys.executable, "-m", "app.cli", "simulate-trial", "--help"],
                         capture_output=True, text=True, check=True).stdout
    assert "--scenario" in out and "--theta" in out
