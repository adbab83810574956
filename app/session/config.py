"""One configuration file for a lab (``--config lab.toml``), read by ``serve``, ``run-session``,
``simulate-trial`` and ``check-devices``: the controller's tables (``[arm]``, ``[cycle]``, ``[dmp]``,
``[scene]``, ``[safety]``, ``[hand]``, ``[loop]``, ``[ur]``, ``[hand_source]``, ``[gripper]``,
``[release]``, see :mod:`robot_io.config`) plus ``[protocol]`` (the study's counts, Sect. V-C) and
``[learner]`` (acquisition and θ box). Every key has a documented default (the paper's where it has
one); an unknown table or key is an error naming it. ``docs/hardware.md`` has a full example.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from pydantic import BaseModel, ConfigDict, create_model

from robot_io.config import ControllerConfig
from robot_io.errors import ConfigError
from robot_io.simulated_hand import Scenario
from session_store.models import StudyConfig

#: The fields of a participant's StudyConfig that a lab sets in [protocol] and [learner]; their
#: types, bounds and documentation are StudyConfig's own.
PROTOCOL_FIELDS = ("initial_trials", "batch_size", "learning_batches", "best_trials",
                   "validation_batches")
LEARNER_FIELDS = ("acquisition", "theta_bounds")
_FROZEN = ConfigDict(frozen=True, extra="forbid")


def _settings(name: str, fields: tuple[str, ...], doc: str) -> type[BaseModel]:
    definitions = {field: (StudyConfig.model_fields[field].annotation, StudyConfig.model_fields[field])
                   for field in fields}
    return create_model(name, __config__=_FROZEN, __doc__=doc, **definitions)


ProtocolSettings = _settings("ProtocolSettings", PROTOCOL_FIELDS,
                             "[protocol]: the counts of the study's phases (the paper's by default).")
LearnerSettings = _settings("LearnerSettings", LEARNER_FIELDS,
                            "[learner]: the acquisition function and the θ box (Table I).")


class LabConfig(ControllerConfig):
    """Everything a lab configures, in one file."""

    protocol: ProtocolSettings = ProtocolSettings()
    learner: LearnerSettings = LearnerSettings()

    @property
    def controller(self) -> ControllerConfig:
        return ControllerConfig.model_validate(
            self.model_dump(exclude={"protocol", "learner"}))

    def study_config(self, scenario: Scenario, seed: int) -> StudyConfig:
        """A new participant's session plan under this configuration."""
        return StudyConfig(scenario=scenario, seed=seed, controller=self.controller,
                           **self.protocol.model_dump(), **self.learner.model_dump())

    def with_rig(self, **tables: BaseModel) -> LabConfig:
        """A copy with some controller tables replaced (rehearsal, ``--ur-host``)."""
        return self.model_copy(update=tables)


def load_lab_config(path: Path | None) -> LabConfig:
    """The lab configuration in ``path`` (the documented defaults for None)."""
    if path is None:
        return LabConfig()
    try:
        data = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"config file {path}: {exc}") from exc
    return LabConfig.model_validate(data)
