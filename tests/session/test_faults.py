"""Staged faults belong to a rehearsal: on any other rig they are refused, and nothing changes."""

from __future__ import annotations

import pytest
from support.engine import SHORT_PROTOCOL

from app.protocol.errors import RefusedAction
from app.session.config import LabConfig
from app.session.faults import StagedFault
from app.session.runner import SessionRunner
from robot_io.hands.simulated_hand import Scenario


@pytest.mark.parametrize("fault", list(StagedFault))
def test_a_fault_is_staged_only_in_a_rehearsal(tmp_path, fault):
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    runner = SessionRunner(tmp_path / "study", lab, realtime=False)
    try:
        runner.open("M01", Scenario.PERTURBED, seed=1)
        with pytest.raises(RefusedAction, match="only in a rehearsal"):
            runner.stage_fault(fault)
        with pytest.raises(RefusedAction, match="only in a rehearsal"):
            runner.refuse_object(True)
        view = runner.view
        assert not view.rehearsal and not view.refusing_object
        assert not any("staged" in m or "take the object" in m for m in view.messages)
    finally:
        runner.close()
