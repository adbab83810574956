"""The participant's tablet: one thing at a time, rendered from the session state alone.

Screens: "Please wait" (nothing to do), "Go!" (a trial runs; with a beep), the relative scale (place
the last handover), the validation rating (better / the same / worse than the previous one), one
question at a time (Q1–Q3), "Thank you". The tablet never shows θ, phase names or anything else that
tells conditions apart, and its only actions are placing, rating and answering. Each action names
the interaction its screen showed, so a stale screen (a reload, a double tap) cannot rate twice.
"""

from __future__ import annotations

import logging
import threading
from typing import Literal

import viser
from pydantic import BaseModel, ConfigDict

from app.protocol.state import Marker, Step
from app.session.runner import RunnerView, SessionRunner
from app.ui.scale_view import render_scale, screen_text, snap
from app.ui.style import TABLET_CSS, audio_cue, style_block
from robot_io.stages import Stage
from session_store.errors import RefusedAction
from session_store.models import QUESTION_BY_ID, QUESTIONS

log = logging.getLogger(__name__)

#: Validation ratings as the participant reads them → the engine's values.
RATINGS: tuple[tuple[str, str], ...] = (("Better", "better"), ("The same", "equal"),
                                        ("Worse", "worse"))

#: The stages of the handover cycle during which the tablet shows "Go!" (before it: please wait).
GO_STAGES = frozenset({Stage.GO, Stage.REACH, Stage.HOLD, Stage.RELEASE})

ScreenKind = Literal["wait", "go", "place", "rate", "question", "done"]


class Screen(BaseModel):
    """What the tablet shows; two equal screens render the same."""

    model_config = ConfigDict(frozen=True)

    kind: ScreenKind
    interaction: int | None = None
    label: int | None = None  # the handover's number within the batch
    markers: tuple[Marker, ...] = ()
    question: str | None = None


def screen_for(view: RunnerView) -> Screen:
    """The participant's screen for the session's state."""
    state = view.state
    if state is None:
        return Screen(kind="wait")
    step, slot = state.step, state.slot
    if step is Step.RUNNING and state.stage in GO_STAGES:  # the cue: the robot starts with it
        return Screen(kind="go", interaction=slot.interaction)
    if step is Step.PLACE:
        return Screen(kind="place", interaction=slot.interaction, label=slot.position,
                      markers=tuple(state.markers))
    if step is Step.RATE:
        return Screen(kind="rate", interaction=slot.interaction)
    if step is Step.ANSWER:
        return Screen(kind="question",
                      question=next(q.id for q in QUESTIONS if q.id not in state.answers))
    if step is Step.DONE:
        return Screen(kind="done")
    return Screen(kind="wait")


def answer_options(question: str) -> list[tuple[str, str]]:
    """(button text, stored value) of a question's answers: 1–5 with the paper's end labels, or
    the words themselves."""
    q = QUESTION_BY_ID[question]
    if not q.numeric:
        return [(answer, answer) for answer in q.answers]
    return [(f"{i} – {text}" if not text.isdigit() else text, str(i))
            for i, text in enumerate(q.answers, start=1)]


class TabletClient:
    """One connected tablet. :meth:`show` redraws only when the screen changed."""

    def __init__(self, client: viser.ClientHandle, runner: SessionRunner) -> None:
        self.client, self.runner = client, runner
        self.screen: Screen | None = None
        self._lock = threading.Lock()

    def show(self, screen: Screen) -> None:
        with self._lock:
            if screen == self.screen:
                return
            self.screen = screen
            gui = self.client.gui
            with self.client.atomic():
                gui.reset()
                gui.add_html(style_block(TABLET_CSS))
                build = {"wait": self._wait, "go": self._go, "place": self._place,
                         "rate": self._rate, "question": self._question, "done": self._done}
                build[screen.kind](gui, screen)

    # -- the screens: each adds its handles and callbacks ----------------------------------------
    def _wait(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Please wait", "The next handover is being prepared."))

    def _go(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Go!", "Take the object from the robot.", "hl-go") + audio_cue())

    def _done(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Thank you!", "The session is complete."))

    def _place(self, gui: viser.GuiApi, screen: Screen) -> tuple[viser.GuiSliderHandle,
                                                                 viser.GuiButtonHandle]:
        gui.add_html(screen_text(f"Handover {screen.label}",
                                 "Drag the orange handle to where this handover belongs. "
                                 "Drop it on a number if it felt the same."))
        markers = list(screen.markers)
        scale = gui.add_html(render_scale(markers, screen.label, 0.5))
        slider = gui.add_slider("", min=0.0, max=1.0, step=0.001, initial_value=0.5)
        confirm = gui.add_button("Confirm", color="green")

        @slider.on_update
        def _(_: viser.GuiEvent) -> None:
            scale.content = render_scale(markers, screen.label, slider.value)

        @confirm.on_click
        def _(_: viser.GuiEvent) -> None:
            landed = snap(slider.value, markers)
            self._act(lambda: self.runner.place(
                screen.interaction, position=None if landed else round(slider.value, 3),
                equal_to=landed.interaction if landed else None))

        return slider, confirm

    def _rate(self, gui: viser.GuiApi, screen: Screen) -> list[viser.GuiButtonHandle]:
        gui.add_html(screen_text("Compared with the previous handover, this one was …",
                                 kind="hl-question"))
        return [self._choice(gui, text, lambda value=value: self.runner.rate(screen.interaction,
                                                                             value))
                for text, value in RATINGS]

    def _question(self, gui: viser.GuiApi, screen: Screen) -> list[viser.GuiButtonHandle]:
        gui.add_html(screen_text(QUESTION_BY_ID[screen.question].text, kind="hl-question"))
        return [self._choice(gui, text, lambda value=value: self.runner.answer(screen.question,
                                                                               value))
                for text, value in answer_options(screen.question)]

    def _choice(self, gui: viser.GuiApi, text: str, action) -> viser.GuiButtonHandle:
        button = gui.add_button(text)
        button.on_click(lambda _: self._act(action))
        return button

    def _act(self, action) -> None:
        """A participant's action; a refusal (stale screen, double tap) is logged, not shown: the
        screen is redrawn from the state anyway."""
        try:
            action()
        except RefusedAction as exc:
            log.warning("tablet action refused: %s", exc)
        self.show(screen_for(self.runner.view))


class Tablet:
    """The tablet server: one :class:`TabletClient` per connection, redrawn on every change."""

    def __init__(self, server: viser.ViserServer, runner: SessionRunner) -> None:
        self.server, self.runner = server, runner
        self.clients: dict[int, TabletClient] = {}
        server.gui.configure_theme(show_logo=False, show_share_button=False, control_width="large")
        server.gui.main_panel.dock_left()
        server.gui.main_panel.set_width(4000)
        server.scene.configure_environment_map(hdri=None)
        server.on_client_connect(self._connect)
        server.on_client_disconnect(lambda client: self.clients.pop(client.client_id, None))
        runner.subscribe(self.refresh)

    def _connect(self, client: viser.ClientHandle) -> None:
        tablet = self.clients[client.client_id] = TabletClient(client, self.runner)
        tablet.show(screen_for(self.runner.view))

    def refresh(self, view: RunnerView) -> None:
        screen = screen_for(view)
        for tablet in list(self.clients.values()):
            tablet.show(screen)
