"""Every limit that guards a person has a hard bound, and no configuration value is infinite or NaN:
a lab config outside them is refused by ``handover`` with the field, the value and the range, before
anything runs — not accepted, not a traceback."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from app.cli import main
from robot_io.hands.config import SimulatedSource

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
    ("[hand]\nmax_speed = 0", "hand.max_speed = 0: must be a finite number in (0, 10] m/s"),
    # the simulated hand's reaches (peak 1.875 × mean) would be refused as tracker jumps
    ("[hand]\nmean_speed_mps = [0.5, 2.0]", "hand.mean_speed_mps = (0.5, 2.0) makes reaches that "
     "peak at 3.75 m/s, beyond hand.max_speed = 3 m/s"),
    ("[release]\ntimeout_s = inf", "release.timeout_s = inf: must be a finite number in (0, 60] s"),
    ("[ur]\nconnect_timeout_s = inf", "ur.connect_timeout_s = inf: must be a finite number in (0, 120] s"),
    ("[scene]\nbox = [1e308, 0.25, 0.15]", "scene.box.0 = 1e+308: must be a finite number in [-3, 3] m"),
    ("[dmp]\ntau0 = nan", "dmp.tau0 = nan: Input should be a finite number"),
    # a singular rotation squashes the hand onto a plane, a reflection mirrors it
    ("[hand_source]\nrotation = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]",
     "hand_source.rotation = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]: must be "
     "orthonormal (|RᵀR − I| ≤ 0.001, here 1) with determinant +1 (here 0)"),
    ("[hand_source]\nrotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]",
     "hand_source.rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]: must be "
     "orthonormal (|RᵀR − I| ≤ 0.001, here 0) with determinant +1 (here -1)"),
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



@settings(max_examples=50)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_every_rotation_to_six_decimals_is_a_proper_rotation(quaternion):
    """Whatever the rotation, its entries as `handover calibrate-tracker` prints them (6 decimals)
    pass the check; so do they with the third row negated and the first two swapped, and never
    with one row negated (a reflection)."""
    rows = Rotation.from_quat(quaternion).as_matrix().round(6)
    SimulatedSource(rotation=rows.tolist())
    SimulatedSource(rotation=rows[[1, 0, 2]] * [[1], [1], [-1]])
    with pytest.raises(ValueError, match="determinant"):
        SimulatedSource(rotation=(rows * [[1], [1], [-1]]).tolist())
