"""Which dashboard window controls the session: the first unlocked while none controls; the others
view-only until one takes control; after the controlling one closes, the one left, or none (of
several) until one takes control or is unlocked."""

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

    windows.opened(3, "10.0.0.7")
    windows.closed(2)  # the controlling window closes (or reloads) with two left: none controls
    assert not windows.status(1).controlling and not windows.status(3).controlling
    assert "no window controls the session" in windows.status(1).words()
    windows.opened(4, "10.0.0.9")  # its reload, unlocked again: it controls
    assert windows.status(4).controlling and not windows.status(1).controlling
    windows.closed(3)
    windows.closed(4)  # one window left: it controls
    assert windows.status(1).controlling and windows.status(1).words() == ""


def test_a_reloaded_window_unlocked_before_its_old_page_closed_controls_once_it_has() -> None:
    windows = DashboardWindows()
    windows.opened(1, "127.0.0.1")
    windows.opened(2, "127.0.0.1")  # the reload, unlocked before the server saw page 1 close
    assert not windows.status(2).controlling
    windows.closed(1)
    assert windows.status(2).controlling


def test_a_window_that_is_not_unlocked_cannot_take_control() -> None:
    windows = DashboardWindows()
    windows.opened(1, "127.0.0.1")
    with pytest.raises(RefusedAction, match="not unlocked"):
        windows.take(7)
    assert windows.status(1).controlling
