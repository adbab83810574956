"""Scoped handling of warnings that BoTorch and linear_operator raise in normal operation.

Only the named categories are absorbed (logged at DEBUG), only inside the block, and every other
warning is re-emitted unchanged, so nothing is silenced process-wide.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

logger = logging.getLogger(__name__)


@contextmanager
def expected_warnings(*categories: type[Warning], context: str) -> Iterator[None]:
    """Absorb warnings of ``categories`` raised in the block; re-emit all others."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for w in caught:
        if issubclass(w.category, categories):
            logger.debug("%s: expected %s: %s", context, w.category.__name__, w.message)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
