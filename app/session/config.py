"""One configuration file for a lab (``--config lab.toml``), read by ``serve``, ``run-session``,
``simulate-trial`` and ``check-devices``: the controller's tables (``[arm]``, ``[cycle]``,
``[dmp]``, ``[scene]``, ``[safety]``, ``[hand]``, ``[loop]``, ``[ur]``, ``[hand_source]``,
``[gripper]``, ``[release]``, see :mod:`robot_io.config`) plus ``[protocol]`` (the study's counts,
Sect. V-C), ``[learner]`` (acquisition, θ box, recommendation, prior), ``[record]`` (the study's LSL
outlets), ``[recording]`` (the session's own XDF recording), ``[safety_record]`` (each trial's
safety record and the lab's limits) and ``[study]`` (the design and counterbalancing of new
participants). Every key has a documented default (the paper's where it has one; ``[study]`` has
none: without it there is no plan); an unknown table or key is an error naming it.
``docs/hardware.md`` has a full example.
"""

from __future__ import annotations

import math
import re
import stat
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

import annotated_types
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo

from app.protocol.design import Assignment, StudyPlan
from app.protocol.safety_record import SafetyRecordSettings
from app.protocol.study_config import PRESETS, StudyConfig
from robot_io.config import ControllerConfig
from robot_io.errors import ConfigError
from robot_io.hands.simulated_hand import Scenario

#: The fields of a participant's StudyConfig that a lab sets in [protocol] and [learner]; their
#: types, bounds and documentation are StudyConfig's own.
PROTOCOL_FIELDS = ("initial_trials", "batch_size", "learning_batches", "best_trials",
                   "validation_batches", "stop_when_settled", "settled_threshold",
                   "settled_min_batches", "settled_preference", "stop_when_no_gain",
                   "gain_chance", "gain_preference", "gain_min_batches", "coactive", "hint_step",
                   "preset")
LEARNER_FIELDS = ("acquisition", "theta_bounds", "recommendation", "population_prior",
                  "prior_weight", "batch_position_noise", "ties")
_FROZEN = ConfigDict(frozen=True, extra="forbid")
#: The largest configuration file read [bytes]: a lab.toml is a few kB.
MAX_CONFIG_BYTES = 1_000_000


def _whole_number_in(low: int, high: int) -> BeforeValidator:
    """Refuse anything but a whole number in [low, high] (``inf``, ``2.5``, ``30``) with the range."""

    def check(value: Any) -> Any:
        whole = (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and math.isfinite(value) and value.is_integer())
        if not (whole and low <= value <= high):
            raise ValueError(f"must be a whole number in [{low}, {high}]")
        return value

    return BeforeValidator(check)


def _annotation(field: FieldInfo) -> Any:
    """The field's type; a bounded integer also names its range in every refusal."""
    low = next((m.ge for m in field.metadata
                if isinstance(m, annotated_types.Ge) and isinstance(m.ge, int)), None)
    high = next((m.le for m in field.metadata
                 if isinstance(m, annotated_types.Le) and isinstance(m.le, int)), None)
    if field.annotation is int and low is not None and high is not None:
        return Annotated[int, _whole_number_in(low, high)]
    return field.annotation


def _settings(name: str, fields: tuple[str, ...]) -> type[BaseModel]:
    """A frozen model of ``fields`` of StudyConfig, made at run time: mypy cannot see its fields, so
    the classes below that extend it read them as Any (``type: ignore[misc]``)."""
    definitions: dict[str, Any] = {field: (_annotation(StudyConfig.model_fields[field]),
                                           StudyConfig.model_fields[field]) for field in fields}
    return create_model(name, __config__=_FROZEN, **definitions)


class ProtocolSettings(_settings("_ProtocolCounts", PROTOCOL_FIELDS)):  # type: ignore[misc]
    """[protocol]: the counts of the study's phases (the paper's by default)."""

    without_learning: bool = Field(
        False, description="say so to run learning_batches = 0: sessions in which θ is never "
                           "learned (no learning batch), e.g. to pilot the tablet or the rig")

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data: Any) -> Any:
        """``preset`` sets its keys (app.protocol.study_config.PRESETS); the lab's own keys win."""
        if isinstance(data, dict) and data.get("preset") in PRESETS:
            return {**PRESETS[data["preset"]], **data}
        return data

    @model_validator(mode="after")
    def _learns_unless_told_not_to(self) -> ProtocolSettings:
        """A protocol without learning batches never learns θ (Sect. III-C: the GP is fitted on
        the comparisons of the batches); it runs only when the lab says so."""
        if self.learning_batches == 0 and not self.without_learning:
            raise ValueError("learning_batches = 0 runs sessions that never learn θ (no learning "
                             "batch): set learning_batches in [1, 50], or without_learning = true "
                             "to run them anyway")
        if self.learning_batches > 0 and self.without_learning:
            raise ValueError(f"without_learning = true contradicts learning_batches = "
                             f"{self.learning_batches}: it goes with learning_batches = 0 only")
        return self

    @model_validator(mode="after")
    def _one_stopping_rule(self) -> ProtocolSettings:
        if self.stop_when_settled and self.stop_when_no_gain:
            preset = {key: f' (preset = "{self.preset}" sets it)' for key in PRESETS[self.preset]}
            raise ValueError(f"stop_when_settled{preset.get('stop_when_settled', '')} and "
                             f"stop_when_no_gain{preset.get('stop_when_no_gain', '')} are both "
                             "true: learning stops by one rule; set one of them to false")
        return self

    def counts(self) -> dict[str, Any]:
        """The phase counts, the early stop, the hints and the preset of a participant's
        :class:`StudyConfig`."""
        return self.model_dump(include=set(PROTOCOL_FIELDS))


class LearnerSettings(_settings("_LearnerFields", LEARNER_FIELDS)):  # type: ignore[misc]
    """[learner]: the acquisition function, the θ box (Table I), how θ* is recommended and the
    opt-in prior from earlier participants."""


class RecordSettings(BaseModel):
    """[record]: what a session publishes for the lab's own recording (docs/hardware.md, "The
    study's LSL outlets")."""

    model_config = _FROZEN

    lsl_outlets: bool = Field(
        True, description="publish the robot stream (one sample per control cycle) and the marker "
                          "stream on Lab Streaming Layer while a session runs on the wall clock "
                          "(a session on simulated time has no LSL time and publishes nothing)")
    lsl_name: str = Field(
        "handover", description="the streams are named '<lsl_name>-robot' and '<lsl_name>-markers' "
                                "(1 to 64 letters, digits, '_', '.', '-'); their source_id adds the "
                                "participant code")

    @field_validator("lsl_name")
    @classmethod
    def _stream_name(cls, value: str) -> str:
        if not re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", value):
            raise ValueError(f"lsl_name = {value!r}: must be 1 to 64 letters, digits, '_', '.' or "
                             "'-' (it begins the names of the study's LSL streams)")
        return value


class RecordingSettings(BaseModel):
    """[recording]: the XDF recording the session itself starts and stops (docs/hardware.md, "The
    session's own recording"): none, LabRecorder's engine in a process of the session
    (``labrecorder``, the ``record`` extra), or the lab's LabRecorder over its remote control port
    (``labrecorder_rcs``)."""

    model_config = _FROZEN

    kind: Literal["none", "labrecorder", "labrecorder_rcs"] = Field(
        "none", description="none: the session records nothing itself; labrecorder: it records with "
                            "LabRecorder's engine into the study folder; labrecorder_rcs: it drives "
                            "the lab's LabRecorder over its remote control (EnableRCS)")
    streams: list[Annotated[str, Field(min_length=1, max_length=200)]] = Field(
        [], max_length=50, description="the lab's streams to record beside the session's own, each "
                                       "by its name or its type (e.g. \"Mocap\", \"EEG\")")
    task: str = Field("handover", description="the BIDS task label of the file names (letters and "
                                              "digits)")
    resolve_s: float = Field(2.0, gt=0, le=30, description="how long the lab's streams are looked for "
                                                          "when the session opens [s]")
    start_timeout_s: float = Field(4.0, gt=0, le=30, description="the file must appear within this "
                                                                "long of the start, or the session "
                                                                "does not open [s]")
    stall_s: float = Field(2.0, gt=0, le=60, description="while a trial streams, a file that does not "
                                                        "grow for this long is warned about [s]")
    rcs_host: str = Field("127.0.0.1", min_length=1, description="labrecorder_rcs: the machine "
                                                                "LabRecorder runs on")
    rcs_port: Annotated[int, _whole_number_in(1, 65535)] = Field(
        22345, description="labrecorder_rcs: LabRecorder's remote control port (its RCSPort)")

    @field_validator("task")
    @classmethod
    def _label(cls, value: str) -> str:
        if not re.fullmatch(r"[A-Za-z0-9]{1,64}", value):
            raise ValueError(f"task = {value!r}: must be 1 to 64 letters or digits (a BIDS label)")
        return value


#: The tables of a lab config that are not the controller's.
APPLICATION_TABLES = frozenset({"protocol", "learner", "record", "recording", "safety_record",
                                "study"})


class LabConfig(ControllerConfig):
    """Everything a lab configures, in one file."""

    protocol: ProtocolSettings = ProtocolSettings()
    learner: LearnerSettings = LearnerSettings()
    record: RecordSettings = RecordSettings()
    #: [study]: the design and the counterbalanced assignment of new participants (None: no plan,
    #: the experimenter chooses every scenario; app.protocol.design)
    study: StudyPlan | None = None
    recording: RecordingSettings = RecordingSettings()
    safety_record: SafetyRecordSettings = SafetyRecordSettings()

    @model_validator(mode="after")
    def _records_its_outlets(self) -> LabConfig:
        """The session's recording always holds its own streams."""
        if self.recording.kind != "none" and not self.record.lsl_outlets:
            raise ValueError(f"[recording] kind = {self.recording.kind!r} records the session's LSL "
                             "outlets: set [record] lsl_outlets = true, or [recording] kind = "
                             "\"none\"")
        return self

    @property
    def controller(self) -> ControllerConfig:
        return ControllerConfig.model_validate(self.model_dump(exclude=set(APPLICATION_TABLES)))

    def study_config(self, scenario: Scenario, seed: int,
                     assignment: Assignment | None = None) -> StudyConfig:
        """A new participant's session plan under this configuration (``assignment``: what the
        study plan proposed for it)."""
        return StudyConfig(scenario=scenario, seed=seed, controller=self.controller,
                           assignment=assignment, **self.protocol.counts(),
                           **self.learner.model_dump())

    def with_rig(self, **tables: BaseModel) -> LabConfig:
        """A copy with some controller tables replaced (rehearsal, ``--ur-host``)."""
        return self.model_copy(update=tables)


def load_lab_config(path: Path | None) -> LabConfig:
    """The lab configuration in ``path`` (the documented defaults for None)."""
    if path is None:
        return LabConfig()
    try:
        data = tomllib.loads(read_config_text(Path(path)))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"config file {path}: {exc}") from exc
    return LabConfig.model_validate(data)


def read_config_text(path: Path) -> str:
    """The text of a configuration file: a regular file of at most :data:`MAX_CONFIG_BYTES`
    (``--config /dev/zero`` or a FIFO would be read without end)."""
    if not stat.S_ISREG(path.stat().st_mode):
        raise ConfigError(f"config file {path}: not a regular file (a lab.toml is a text file)")
    with path.open("rb") as file:
        data = file.read(MAX_CONFIG_BYTES + 1)
    if len(data) > MAX_CONFIG_BYTES:
        raise ConfigError(f"config file {path}: larger than {MAX_CONFIG_BYTES // 1000:,} kB, the "
                          "most a lab configuration may have (a lab.toml is a few kB)")
    return data.decode("utf-8")
