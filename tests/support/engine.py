"""Driving a protocol engine in a test: short protocols, one simulated step, up to a given step."""

from __future__ import annotations

import json
from pathlib import Path

from app.protocol.auto import act_once as step_once
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from robot_io.config import ControllerConfig, LoopConfig
from robot_io.hands.simulated_hand import Scenario

#: 3 initial + 1 learning batch of 3 + 1 best + 1 validation pair = 9 interactions
SHORT_PROTOCOL = {"initial_trials": 3, "batch_size": 3, "learning_batches": 1, "best_trials": 1,
         "validation_batches": 1}
#: The briefest protocol a session can end: 2 initial interactions (one comparison), the learned
#: best, the questionnaire; no batch, no pair (3 interactions). For tests about what happens around
#: whole sessions (several participants, the overview, the rig), not about their phases.
BRIEF_PROTOCOL = {"initial_trials": 2, "learning_batches": 0, "without_learning": True,
                  "best_trials": 1, "validation_batches": 0}

#: :data:`SHORT_PROTOCOL` with 4 learning batches that stops learning once settled, easily: the
#: simulated participant (seed 1) settles it after the first batch (64 % sure against a threshold of
#: 50 %, content when the best handover would be preferred to θ* at most 95 % of the time), so the
#: plan of 18 interactions becomes 3 + 3 + 1 + 2 = 9.
STOPPING_PROTOCOL = {**SHORT_PROTOCOL, "learning_batches": 4, "stop_when_settled": True,
                     "settled_threshold": 0.5, "settled_min_batches": 1,
                     "settled_preference": 0.95}


def protocol_toml(protocol: dict[str, int | bool]) -> str:
    """``protocol``'s settings as the body of a lab config's [protocol] table."""
    return "".join(f"{key} = {json.dumps(value)}\n" for key, value in protocol.items())


#: The controller of the sessions that tests drive: the CB-series rate, 125 Hz, a rate a lab
#: configures. A simulated trial then has a quarter of the cycles to compute and of the sample rows
#: to store; nothing the engine, the store, the export or the report does depends on the rate. The
#: 500 Hz loop is tested in tests/robot_io (the loop, the UR) and in the rehearsals.
SESSION_CONTROLLER = ControllerConfig(loop=LoopConfig(rate_hz=125))
#: The same as a lab config file's table, for sessions that tests run as commands (``--config``).
SESSION_LOOP_TOML = f"[loop]\nrate_hz = {SESSION_CONTROLLER.loop.rate_hz}\n"


def study_config(seed: int = 1, scenario: Scenario = Scenario.STRAIGHTFORWARD,
                 **fields: object) -> StudyConfig:
    """A participant's session plan on :data:`SESSION_CONTROLLER`: the paper's protocol, or what
    ``fields`` set."""
    return StudyConfig(scenario=scenario, seed=seed, controller=SESSION_CONTROLLER, **fields)


def short_config(seed: int = 1, scenario: Scenario = Scenario.STRAIGHTFORWARD) -> StudyConfig:
    return study_config(seed, scenario, **SHORT_PROTOCOL)


def brief_config(seed: int = 1) -> StudyConfig:
    """A participant's plan of :data:`BRIEF_PROTOCOL` (its lab-config switch is not the plan's)."""
    return study_config(seed, **{key: value for key, value in BRIEF_PROTOCOL.items()
                                 if key != "without_learning"})


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


def closed_session(study: Path, code: str, until: Step = Step.DONE, **kwargs) -> Path:
    """``code``'s short session (``kwargs``: :func:`short_config`'s), driven until it waits for
    ``until`` and closed as a writer closes it; its database."""
    engine = new_engine(study, code, **kwargs)
    drive_until(engine, until)
    engine.close()
    return engine.store.path
