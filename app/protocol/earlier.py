"""The prior from earlier participants of a study folder (``[learner] population_prior``, opt-in).

When a new participant's session is created with ``StudyConfig.population_prior``, the GP prior mean
of eq. (12) becomes the pooled posterior mean of the *completed* participants (session done) of the
same scenario and the same θ box in the study folder, each taken from its last stored learner
snapshot (:func:`app.learning.pooled_prior.population_prior`; weight ``prior_weight``). The prior is
fixed at creation and stored in the session (``session_created``: its sources in the config's
``prior_sources``, the prior itself in the event), so a resumed session, an export and a replay see
exactly the prior the participant had, whatever happens to the folder later.

The prior is computed in a spawned process: it rebuilds the earlier participants' GPs, and torch
stays out of the session's process, as with the learner itself (:mod:`app.learning.worker`).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from app.learning.config import LearnerSnapshot
from app.learning.errors import LearningError
from app.learning.prior import PopulationPrior
from app.protocol.plan import protocol_slots
from app.protocol.state import Step, replay
from app.protocol.study_config import StudyConfig
from session_store.errors import StoreError
from session_store.read_only_copy import reading
from session_store.store import participant_codes

log = logging.getLogger(__name__)


def completed_snapshots(study_dir: Path, code: str, config: StudyConfig) -> dict[str, LearnerSnapshot]:
    """The final learner snapshot of every other participant of ``study_dir`` whose session is
    done, with ``config``'s scenario and θ box, by participant code (sorted)."""
    found: dict[str, LearnerSnapshot] = {}
    for other in participant_codes(study_dir):
        if other == code:
            continue
        try:
            with reading(study_dir, other) as store:  # an in-memory copy: the file is not touched
                earlier = StudyConfig.model_validate(store.participant().config)
                if (earlier.scenario, earlier.theta_bounds) != (config.scenario,
                                                                config.theta_bounds):
                    continue
                if replay(protocol_slots(earlier), store.events()).step is not Step.DONE:
                    continue
                rows = store.rows("learner_snapshots")
        except StoreError as exc:
            log.warning("participant %s left out of the prior: %s", other, exc)
            continue
        if rows:
            found[other] = LearnerSnapshot.model_validate_json(rows[-1].state)
    return found


def _pooled(snapshots: dict[str, LearnerSnapshot], weight: float) -> PopulationPrior:
    from app.learning.pooled_prior import population_prior  # torch: only in the spawned process

    return population_prior(snapshots, weight=weight)


def earlier_participants_prior(study_dir: Path, code: str,
                               config: StudyConfig) -> PopulationPrior | None:
    """The prior for participant ``code`` from the completed participants of its study folder;
    None when there is none (the first participants of a study) or none has a fitted model."""
    snapshots = completed_snapshots(study_dir, code, config)
    if not snapshots:
        log.info("participant %s: no completed participant of scenario %s yet, no prior", code,
                 config.scenario.value)
        return None
    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        try:
            return pool.submit(_pooled, snapshots, config.prior_weight).result()
        except LearningError as exc:
            log.warning("participant %s: no prior (%s)", code, exc)
            return None
