"""Every trial's safety record (issue 47): how close and how fast the robot came to the person,
computed from the trial's stored sample rows (one per control cycle, :mod:`robot_io.control.recorder`).

- **distance**: ‖p_tool − p_hand‖, the measured TCP to the tracked hand. The loop repeats the latest
  hand sample until the tracker's next one (``hand_t``), so the hand is taken at the tracker's own
  samples and interpolated linearly onto each cycle's time (the tracker's steps would otherwise read
  as speeds of a step over one cycle).
- **speed near the hand**: the TCP's speed ‖ṗ_tool‖ (central differences over the cycles' times)
  whenever the distance is within ``near_radius_m``; its largest value.
- **closing speed**: −d(distance)/dt, positive while tool and hand approach each other, whenever
  the distance is within ``near_radius_m``; its largest value.
- **pull to open**: from the start of the contact that ran into the release — the pull
  (‖F̃ − F₀‖, :mod:`robot_io.control.release`) at or above ``contact_pull_n`` through the hold's
  last cycles — to the first cycle of the released stage (the gripper open). The peak pull itself
  is the trial's ``peak_pull_n``.
- **contact**: the longest stretch of the hold in which the pull stays at or above
  ``contact_pull_n``: the person holds on to the object in the robot's grip. ISO/TS 15066 tells
  a transient contact from a quasi-static one by its duration; a contact longer than
  ``contact_hold_s`` (0.5 s) is reported as a hold.

The limits a trial is judged by are the lab's (``[safety_record]``): none is built in, since the
figures of ISO/TS 15066 (and a lab's risk assessment) are the lab's to take from the standard itself
(docs/data.md, "The safety record of every trial").
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from session_store.models import SafetyRecord

_FROZEN = ConfigDict(frozen=True, extra="forbid")
#: The hold's and the released stage's codes in the sample rows (robot_io.control.stages: 1 reach, 2 hold,
#: 3 released); the pull is watched in the hold only (after the release the rows keep its last value).
HOLD, RELEASED = 2.0, 3.0

Limit = Annotated[float | None, Field(gt=0)]


class SafetyRecordSettings(BaseModel):
    """``[safety_record]``: how the record is taken (with defaults) and the lab's limits (none built
    in: a limit left out is not checked)."""

    model_config = _FROZEN

    near_radius_m: float = Field(0.2, gt=0, le=2.0, description="the tool's speed and closing speed "
                                 "are taken whenever the hand is within this distance of it [m]")
    contact_pull_n: float = Field(2.0, gt=0, le=50.0, description="a pull at or above this is "
                                  "contact: the person holds the object in the robot's grip [N]")
    contact_hold_s: float = Field(0.5, gt=0, le=10.0, description="a contact longer than this is "
                                  "reported as a hold (ISO/TS 15066: transient vs quasi-static) [s]")
    min_distance_m: Limit = Field(None, description="the lab's limit: the closest the tool may come "
                                  "to the hand [m]")
    max_speed_near_mps: Limit = Field(None, description="the lab's limit: the tool's speed with the "
                                      "hand near [m/s]")
    max_closing_speed_mps: Limit = Field(None, description="the lab's limit: the closing speed with "
                                         "the hand near [m/s]")
    max_pull_n: Limit = Field(None, description="the lab's limit: the peak pull [N]")
    max_pull_to_open_s: Limit = Field(None, description="the lab's limit: from pull to open [s]")
    max_contact_s: Limit = Field(None, description="the lab's limit: the longest contact [s]")


#: The record's settings where the lab sets none (the engine's default).
DEFAULT_SAFETY = SafetyRecordSettings()
#: The record's figures and the trial's column each is judged on, with the limit that judges it and
#: whether the limit is a floor (distance) or a ceiling; the peak pull is the trial's ``peak_pull_n``.
JUDGED: tuple[tuple[str, str, bool], ...] = (
    ("min_distance_m", "min_distance_m", True),
    ("speed_near_mps", "max_speed_near_mps", False),
    ("closing_speed_mps", "max_closing_speed_mps", False),
    ("peak_pull_n", "max_pull_n", False),
    ("pull_to_open_s", "max_pull_to_open_s", False),
    ("longest_contact_s", "max_contact_s", False),
)


def _spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _hand_at_cycles(t: np.ndarray, hand: np.ndarray, hand_t: np.ndarray) -> np.ndarray:
    """The hand interpolated onto the cycles' times ``t`` from the tracker's own samples (where
    ``hand_t`` changes), held at its first and last sample outside them."""
    fresh = np.flatnonzero(np.concatenate([[True], np.diff(hand_t) != 0]))
    if len(fresh) < 2:
        return hand
    return np.stack([np.interp(t, hand_t[fresh], hand[fresh, axis]) for axis in range(3)], axis=1)


def safety_record(rows: dict[str, np.ndarray], settings: SafetyRecordSettings) -> SafetyRecord:
    """The record of one trial from its sample rows (:func:`session_store.sample_rows.stored_rows`
    columns, or the loop's own)."""
    parameters = {"near_radius_m": settings.near_radius_m, "contact_pull_n": settings.contact_pull_n}
    t, tool, hand = rows["t"], rows["measured"], rows["hand"]
    valid = np.isfinite(t) & np.isfinite(tool).all(axis=1) & np.isfinite(hand).all(axis=1) & \
        np.isfinite(rows["hand_t"])
    figures: dict[str, float | None] = {}
    if valid.sum() >= 2:
        tv, toolv = t[valid], tool[valid]
        handv = _hand_at_cycles(tv, hand[valid], rows["hand_t"][valid])
        distance = np.linalg.norm(toolv - handv, axis=1)
        speed = np.linalg.norm(np.gradient(toolv, tv, axis=0), axis=1)
        closing = -np.gradient(distance, tv)
        near = distance <= settings.near_radius_m
        figures["min_distance_m"] = float(distance.min())
        figures["speed_near_mps"] = float(speed[near].max()) if near.any() else None
        figures["closing_speed_mps"] = float(closing[near].max()) if near.any() else None
    pull = np.nan_to_num(rows["pull"], nan=0.0)
    timed = np.isfinite(t)
    contacts = _spans((pull >= settings.contact_pull_n) & (rows["stage"] == HOLD) & timed)
    durations = [float(t[b - 1] - t[a]) for a, b in contacts]
    released = np.flatnonzero((rows["stage"] == RELEASED) & timed)
    leading = [a for a, b in contacts if len(released) and b == released[0]]
    if leading:  # the contact that ran into the release: the pull that opened the gripper
        figures["pull_to_open_s"] = float(t[released[0]] - t[leading[0]])
    return SafetyRecord(**figures, longest_contact_s=max(durations, default=0.0), **parameters)


def over_limits(figures: dict[str, float | None], settings: SafetyRecordSettings) -> list[str]:
    """Each of a trial's ``figures`` (its row's safety columns and ``peak_pull_n``) past the lab's
    limit, in words; a contact is reported once it is longer than ``contact_hold_s``, limit or not."""
    over = []
    for figure, limit, floor in JUDGED:
        value, bound = figures.get(figure), getattr(settings, limit)
        if value is None or bound is None:
            continue
        if (value < bound) if floor else (value > bound):
            over.append(f"{figure} {value:.3g} {'<' if floor else '>'} {bound:g} ({limit})")
    contact = figures.get("longest_contact_s")
    if contact is not None and contact > settings.contact_hold_s and settings.max_contact_s is None:
        over.append(f"a contact held {contact:.2f} s (> contact_hold_s {settings.contact_hold_s:g})")
    return over


def rebuilt_differences(records: dict[int, SafetyRecord],
                        samples: dict[int, dict[str, np.ndarray]]) -> list[str]:
    """Where each trial's stored safety record (``records``, from its trial_ended event) differs
    from the one its stored ``samples`` give, taken again with the record's own parameters
    (``handover doctor``), one sentence per trial."""
    problems = []
    for index, stored in sorted(records.items()):
        assert stored.near_radius_m is not None and stored.contact_pull_n is not None, \
            "a record carries the parameters it was taken with"
        settings = SafetyRecordSettings(near_radius_m=stored.near_radius_m,
                                        contact_pull_n=stored.contact_pull_n)
        rebuilt = safety_record(samples[index], settings)
        differ = [name for name, value in stored.model_dump().items()
                  if not _same(value, getattr(rebuilt, name))]
        if differ:
            problems.append(f"trials: trial {index}'s safety record differs from its samples in "
                            + ", ".join(f"{name} (stored {getattr(stored, name)!r}, samples give "
                                        f"{getattr(rebuilt, name)!r})" for name in differ))
    return problems


def _same(a: float | None, b: float | None) -> bool:
    return a == b or (a is not None and b is not None and bool(np.isclose(a, b, rtol=1e-9, atol=1e-12)))
