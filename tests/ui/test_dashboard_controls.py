"""The dashboard's session controls against a real viser server, in process: a refresh of the view does
not overwrite the experimenter's tick of "Simulated participant rates" while that tick is on its way
to the session.

viser sets a box's value from the page's message, then runs the box's callback in a thread; the
callback reads the box's value and switches the simulated participant. A refresh in between (any
other change of the session: a trial's stage, the tablet) used to set the box back to the view's
old value, so the callback switched the simulated participant off again: the click was lost and the
box showed unticked (the browser tests' "click did not land", retried blindly before).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import viser

from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState
from app.session.config import LabConfig
from app.session.runner import RunnerView
from app.ui.dashboard import Controls
from robot_io.hands.simulated_hand import Scenario

SLOTS = protocol_slots(LabConfig().study_config(Scenario.PERTURBED, 0))


@pytest.fixture
def controls() -> Iterator[Controls]:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    gui = server.gui
    try:
        yield Controls(start=gui.add_button("Start trial"), start_why=gui.add_markdown(""),
                       gates={"prepare": gui.add_button("Object loaded"),
                              "ready": gui.add_button("Go")},
                       abort=gui.add_button("Abort trial"), recover=gui.add_button("Recover arm"),
                       pause=gui.add_button("Pause session"), resume=gui.add_button("Resume"),
                       end=gui.add_button("End session"),
                       auto=gui.add_checkbox("Simulated participant rates", False))
    finally:
        server.stop()


def view(auto: bool, version: int) -> RunnerView:
    return RunnerView(version=version, code="P01", scenario=Scenario.PERTURBED,
                      auto=auto,
                      state=SessionState(slots=SLOTS, cursor=0))


def test_a_refresh_keeps_a_tick_on_its_way_and_shows_each_change_of_the_session(
        controls: Controls) -> None:
    controls.enable_for(view(auto=False, version=1), controlling=True)
    assert controls.auto.value is False
    controls.auto.value = True  # the experimenter's tick, as viser holds it before the callback runs
    controls.enable_for(view(auto=False, version=2), True)  # a refresh for another change meanwhile
    assert controls.auto.value is True, "the refresh overwrote the tick on its way"
    controls.enable_for(view(auto=True, version=3), controlling=True)  # the session took it
    assert controls.auto.value is True
    controls.enable_for(view(auto=False, version=4), True)  # switched off (another page, an end)
    assert controls.auto.value is False
    controls.enable_for(view(auto=False, version=5), controlling=True)
    assert controls.auto.value is False


def test_a_view_only_window_enables_no_control_and_says_why(controls: Controls) -> None:
    controls.enable_for(view(auto=False, version=1), controlling=False)
    assert all(button.disabled for button in (
        controls.start, *controls.gates.values(), controls.abort, controls.recover,
        controls.pause, controls.resume, controls.end, controls.auto))
    assert "view-only" in controls.start_why.content
