"""Which dashboard window controls the session: the first unlocked while none controls; the others
view-only until one takes control; none after the controlling one closes, until one takes control
or is unlocked."""

from __future__ import annotations

import pytest

from app.protocol.errors import RefusedAction
from app.session.windows import DashboardWindows


def test_one_window_controls_and_every_window_is_told_of_the_others() -> None:
    windows = DashboardWindows()
    windows.opened(1, "10.0.0.5")
    assert windows.status(1).words() == ""  # alone: nothing to say
    windows.opened(2, "10.0.0.9")
    first, second = windows.status(1), windows.status(2)
    assert (first.controlling, second.controlling) == (True, False)
    assert "2 dashboard windows are open** (10.0.0.5, 10.0.0.9)" in first.words()
    assert "This window controls the session" in first.words()
    assert "view-only**: the window at 10.0.0.5 controls" in second.words()
    windows.require_control(1)
    with pytest.raises(RefusedAction, match="view-only"):
        windows.require_control(2)

    windows.take(2)  # the experimenter decides on the second window
    windows.require_control(2)
    with pytest.raises(RefusedAction, match="view-only"):
        windows.require_control(1)

    windows.closed(2)  # the controlling window closes (or reloads): none controls
    assert not windows.status(1).controlling
    assert "no window controls the session" in windows.status(1).words()
    windows.opened(3, "10.0.0.9")  # its reload, unlocked again: it controls
    assert windows.status(3).controlling and not windows.status(1).controlling


def test_a_window_that_is_not_unlocked_cannot_take_control() -> None:
    windows = DashboardWindows()
    windows.opened(1, "127.0.0.1")
    with pytest.raises(RefusedAction, match="not unlocked"):
        windows.take(7)
    assert windows.status(1).controlling
