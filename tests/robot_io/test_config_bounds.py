"""Every limit that guards a person has a hard bound, and no configuration value is infinite or NaN:
a lab config outside them is refused by ``handover`` with the field, the value and the range, before
anything runs — not accepted, not a traceback."""

from __future__ import annotations

import pytest

from app.cli import main

CASES = [
    ("[safety]\nmax_speed = inf", "safety.max_speed = inf: must be a finite number in (0, 1.5] m/s"),
    ("[safety]\nmax_speed = 5.0", "safety.max_speed = 5.0: must be a finite number in (0, 1.5] m/s"),
    ("[safety]\nmax_acceleration = inf",
     "safety.max_acceleration = inf: must be a finite number in (0, 10] m/s²"),
    ("[safety]\nworkspace_min = [-100.0, -100.0, -100.0]\nworkspace_max = [100.0, 100.0, 100.0]",
     "safety.workspace_min.0 = -100.0: must be a finite number in [-1, 1] m"),
    ("[safety]\nworkspace_max = [0.9, nan, 0.8]",
     "safety.workspace_max.1 = nan: must be a finite number in [-1, 1] m"),
    ("[loop]\nstaleness_limit_s = inf",
     "loop.staleness_limit_s = inf: must be a finite number in (0, 0.5] s"),
    ("[loop]\ntimeout_s = inf", "loop.timeout_s = inf: must be a finite number in (0, 120] s"),
    ("[hand]\ntracker_rate_hz = 1e9",
     "hand.tracker_rate_hz = 1000000000.0: must be a finite number in (0, 2000] Hz"),
    ("[release]\ntimeout_s = inf", "release.timeout_s = inf: must be a finite number in (0, 60] s"),
    ("[ur]\nconnect_timeout_s = inf", "ur.connect_timeout_s = inf: must be a finite number in (0, 120] s"),
    ("[scene]\nbox = [1e308, 0.25, 0.15]", "scene.box.0 = 1e+308: must be a finite number in [-3, 3] m"),
    ("[dmp]\ntau0 = nan", "dmp.tau0 = nan: Input should be a finite number"),
]


@pytest.mark.parametrize("toml,message", CASES, ids=[c[0].split("\n")[1] for c in CASES])
def test_an_unbounded_or_non_finite_config_value_is_refused_with_field_value_and_range(
        toml, message, tmp_path, capsys):
    config = tmp_path / "lab.toml"
    config.write_text(toml + "\n")
    code = main(["simulate-trial", "--scenario", "perturbed", "--theta", "5,0,1", "--json",
                 "--config", str(config)])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""  # nothing ran
    assert message in captured.err and "Traceback" not in captured.err

