"""The exceptions of ``app.learning``: every message names the field, the value and the range.

``LearningError`` derives from ``ValueError`` so that the ``handover`` command reports it as bad
input (exit status 2) like the other packages' configuration errors.
"""

from __future__ import annotations


class LearningError(ValueError):
    """Base of every error raised by ``app.learning``."""


class ParameterBoxError(LearningError):
    """A parameter box is malformed, or a point lies outside it or names unknown parameters."""


class ScaleError(LearningError):
    """Placements on the relative scale that cannot be turned into comparisons."""


class UnknownInteractionError(LearningError):
    """A comparison names an interaction the learner has not been told about."""


class StudyError(LearningError):
    """A simulated-study configuration or result file that cannot be used (e.g. resume mismatch)."""


class WorkerError(LearningError):
    """The learner's worker process failed and could not be restarted."""
