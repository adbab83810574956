"""A participant's seed: validated, fresh by default, never silently shared within a study.

The seed drives every random choice of a session (the learner's Sobol points and acquisition
restarts, the validation references and the counterbalanced order of the validation pairs, and with
the simulated participant its taste and noise). It is stored in the participant's configuration, so
it must fit the store: a non-negative integer that fits a signed 64-bit SQLite INTEGER (and pandas'
``Int64`` in the export).

A new participant gets a fresh random seed unless one is given; a seed given explicitly that another
participant of the study already has is refused unless the experimenter confirms the reuse (two
participants with one seed get the same initial θ and the same validation order).
"""

from __future__ import annotations

import secrets
from collections.abc import Container
from pathlib import Path
from typing import Annotated

from pydantic import Field

from app.protocol.errors import RefusedAction
from session_store.catalog import stored_configs

#: The largest seed: 2**63 − 1, a signed 64-bit integer (SQLite INTEGER, pandas Int64).
SEED_MAX = 2**63 - 1
#: Fresh seeds are drawn below this: short enough to read out and type, ample for a study.
FRESH_SEED_LIMIT = 2**32

Seed = Annotated[int, Field(ge=0, le=SEED_MAX,
                            description="seeds the learner, the Sobol points, the order of "
                                        "validation pairs and, with the simulated participant, "
                                        "its ratings and hand; a non-negative integer < 2**63")]


def parse_seed(text: str) -> int:
    """A seed typed on a command line or a form; ``ValueError`` naming the field and range."""
    try:
        value = int(str(text).strip())
    except ValueError:
        raise ValueError(f"seed = {text!r} is not an integer (allowed: 0 … {SEED_MAX})") from None
    if not 0 <= value <= SEED_MAX:
        raise ValueError(f"seed = {value} is outside the allowed range [0, {SEED_MAX}] "
                         "(a non-negative integer that fits in 64 bits)")
    return value


def seeds_in_use(study_dir: Path) -> dict[int, list[str]]:
    """seed → the participants of ``study_dir`` that have it (read-only; unreadable files skipped)."""
    used: dict[int, list[str]] = {}
    for code, config in stored_configs(study_dir).items():
        seed = config.get("seed")
        if isinstance(seed, int):
            used.setdefault(seed, []).append(code)
    return used


def fresh_seed(used: Container[int] = frozenset()) -> int:
    """A random seed (from the OS's entropy) that no participant of the study has yet."""
    while (seed := secrets.randbelow(FRESH_SEED_LIMIT)) in used:
        pass
    return seed


def choose_seed(study_dir: Path, requested: int | None, reuse_confirmed: bool = False) -> int:
    """The seed of a new participant: fresh when none is ``requested``; the ``requested`` one if no
    other participant of the study has it, or if the experimenter confirmed its reuse."""
    used = seeds_in_use(study_dir)
    if requested is None:
        return fresh_seed(used)
    requested = parse_seed(str(requested))
    if requested in used and not reuse_confirmed:
        raise RefusedAction(
            f"seed = {requested} is already used in {study_dir} by {', '.join(used[requested])}: "
            "the same seed gives the same initial θ and validation order. Leave the seed empty for "
            "a fresh one, or confirm the reuse (run-session: --reuse-seed; dashboard: 'Reuse a seed "
            "already used')")
    return requested
