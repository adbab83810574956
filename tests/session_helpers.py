"""Shared set-up for the session tests: short protocols, driving an engine to a given step."""

from __future__ import annotations

from pathlib import Path

from app.protocol.auto import step_once
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.protocol.study import StudyConfig
from robot_io.simulated_hand import Scenario

#: 3 initial + 1 learning batch of 3 + 1 best + 1 validation pair = 9 interactions
SHORT = {"initial_trials": 3, "batch_size": 3, "learning_batches": 1, "best_trials": 1,
         "validation_batches": 1}


def short_config(seed: int = 1, scenario: Scenario = Scenario.STRAIGHTFORWARD) -> StudyConfig:
    return StudyConfig(scenario=scenario, seed=seed, **SHORT)


def drive_until(engine: SessionEngine, step: Step, participant: SimulatedParticipant | None = None,
                max_actions: int = 500) -> None:
    """Let the simulated participant act until the session waits for ``step``."""
    participant = participant or SimulatedParticipant(engine.config.seed)
    for _ in range(max_actions):
        if engine.state.step is step:
            return
        step_once(engine, participant)
    raise AssertionError(f"session never reached {step}")


def new_engine(study: Path, code: str = "S01", **kwargs) -> SessionEngine:
    return SessionEngine.create(study, code, short_config(**kwargs))
