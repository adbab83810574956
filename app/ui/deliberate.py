"""Deliberate answers: a tap only counts on a screen the participant has had time to see.

Psychophysics toolkits (jsPsych's ``response_allowed_while_playing``/``trial_duration`` family,
PsychoPy's ``minDuration``) ignore responses for a short time after a screen appears, so that the
second half of a double tap, or a finger still resting on the glass, does not answer a question the
participant has not read. viser runs no ``<script>`` from the GUI, so the tablet keeps this window
on the server, per connected page: :meth:`Settle.restart` when a screen is drawn,
:meth:`Settle.ready` before acting on any input.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: Input is ignored for this long after each screen change [s].
SETTLE_S = 0.4


class Settle:
    """The time since the page's screen last changed."""

    def __init__(self, settle_s: float = SETTLE_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not 0.0 <= settle_s <= 5.0:
            raise ValueError(f"settle_s = {settle_s} s must lie in [0, 5] s")
        self.settle_s, self._clock = settle_s, clock
        self._shown_at = clock()

    def restart(self) -> None:
        """A new screen was drawn now."""
        self._shown_at = self._clock()

    def ready(self) -> bool:
        """Whether input may count: the screen has been shown for at least ``settle_s``."""
        return self._clock() - self._shown_at >= self.settle_s
