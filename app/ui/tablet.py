"""The participant's tablet: one thing at a time, rendered from the session state alone.

Screens: "Please wait" (nothing to do; it says what comes next), the introduction to the validation
pairs, "Go!" (a trial runs; with a beep), the relative scale (place the last handover), with
``[protocol] coactive`` the hint after each placement (should the robot come sooner, later, react
more or less to the hand, or was it fine), the validation rating (better / the same / worse than the
one before), the questionnaire one question per screen, "Thank you". The tablet never shows θ,
parameter names, phase names or anything else that tells conditions apart, and its only actions are
placing, hinting, rating and answering. Each action names the interaction its screen showed, so a
stale screen (a reload, a double tap) cannot rate twice.
While the simulated participant rates (a demo, a dry run), the tablet says "Please wait" where the
person would answer: it never offers a question that is not theirs to answer.

Answers are deliberate: input counts only once a screen has been seen for
:data:`~app.ui.deliberate.SETTLE_S`; Confirm is disabled until the handle has moved (the scale says
so), and the handle never starts on an earlier marker; a hint, a rating or an answer is a choice
followed by Confirm or Next.

One tablet per session (:mod:`app.session.pairing`): a page on the tablet port becomes the study's
tablet once the pairing code shown on the dashboard is typed on it ("Connect this tablet"); the
pairing holds for that browser across reloads and restarts. Another page of the same browser shows
"This tablet is not in use" and is offered nothing to rate, until the tablet's page closes; a page
of another browser, even from the tablet's address, is offered only the code. The runner hears of every
page (:meth:`SessionRunner.tablet_connected`), so the dashboard shows how many are open and Start
is refused without exactly one paired tablet.

The page is a kiosk: viser's own chrome is hidden by CSS delivered with every screen
(:data:`~app.ui.style.KIOSK_CSS`), and a dropped connection covers the screen with "Please tell the
experimenter" (:data:`~app.ui.style.OFFLINE_CSS`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Literal

import viser
from pydantic import BaseModel, ConfigDict

from app.protocol.errors import RefusedAction
from app.protocol.plan import Rating, Slot
from app.protocol.state import PARTICIPANT_STEPS, Marker, SessionState, Step
from app.session.runner import RunnerView, SessionRunner
from app.ui.deliberate import SETTLE_S, Settle
from app.ui.questionnaire import Draft
from app.ui.scale_view import render_scale, screen_text, snap, start_position
from app.ui.stage_words import stage_words
from app.ui.style import KIOSK_CSS, OFFLINE_CSS, TABLET_CSS, audio_cue, style_block
from session_store.vocabulary import Hint, Phase, Question, question, questions

log = logging.getLogger(__name__)

#: Validation ratings as the participant reads them → the engine's values.
RATINGS: tuple[tuple[str, str], ...] = (("Better", "better"), ("The same", "equal"),
                                        ("Worse", "worse"))
#: The coactive hint's answer "nothing to change" (stored as no hint).
NO_HINT = "none"
#: Coactive hints as the participant reads them (the robot should …) → :class:`Hint`'s values
#: (app/protocol/hints.py says which way each moves θ; the words never name a parameter). Sooner and
#: later say what the robot changes: when it arrives, by waiting less or more for the hand — not
#: when it starts, nor how fast it moves ("Come sooner" read as either).
HINTS: tuple[tuple[str, str], ...] = (("Arrive sooner: wait less for my hand", Hint.SOONER.value),
                                      ("Arrive later: wait more for my hand", Hint.LATER.value),
                                      ("React more to my hand", Hint.MORE.value),
                                      ("React less to my hand", Hint.LESS.value),
                                      ("No, it was fine", NO_HINT))
#: The first line of every screen's CSS block: the kiosk, the offline cover, the tablet's look,
#: and the marker the offline cover looks for.
PAGE_STYLE = style_block(KIOSK_CSS + OFFLINE_CSS + TABLET_CSS) + '<span class="hl-live"></span>'

#: Above the scale while its Confirm is grey, until the handle has moved.
MOVE_FIRST = "Confirm lights up once you move the handle. To keep it here, move it away and back."

ScreenKind = Literal["wait", "pairs", "go", "back", "place", "hint", "rate", "question",
                     "done", "unused", "pair"]


class Screen(BaseModel):
    """What the tablet shows; two equal screens render the same."""

    model_config = ConfigDict(frozen=True)

    kind: ScreenKind
    interaction: int | None = None
    label: int | None = None  # the handover's number within the batch
    markers: tuple[Marker, ...] = ()
    questions: tuple[str, ...] = ()  # the questions still unanswered
    next_up: str = ""  # what "Please wait" announces, in the participant's words


UNUSED = Screen(kind="unused")
PAIR = Screen(kind="pair")


def _next_up(state: SessionState) -> Screen:
    """"Please wait", saying what comes next; before the first validation pair, the pairs' plain
    introduction. Counts are 1-based and never tell the conditions apart."""
    slot = state.slot
    if slot is None:
        return Screen(kind="wait")
    if slot.phase is Phase.VALIDATION:
        if slot.batch == 1 and slot.position == 1:
            return Screen(kind="pairs")
        which = "first" if slot.position == 1 else "second"
        return Screen(kind="wait", next_up=f"Next: the {which} handover of a new pair."
                      if slot.position == 1 else f"Next: the {which} handover of this pair.")
    if slot.rating is Rating.SCALE and slot.batch_size > 1:
        return Screen(kind="wait", next_up=f"Next: handover {slot.position} of {slot.batch_size}.")
    return Screen(kind="wait", next_up="Next: one more handover.")


def screen_for(view: RunnerView) -> Screen:
    """The participant's screen for the session's state."""
    state = view.state
    if state is None:
        return Screen(kind="wait")
    step, slot = state.step, state.slot
    shown = stage_words(state.stage).tablet if step is Step.RUNNING and state.stage else "wait"
    if shown != "wait":  # "go": the cue, the robot starts with it; "back": it moves back
        return Screen(kind=shown, interaction=_current(slot).interaction)
    if view.auto and step in PARTICIPANT_STEPS:
        # the simulated participant answers: the person holding the tablet is asked nothing
        return Screen(kind="wait")
    if step is Step.PLACE:
        placed = _current(slot)
        return Screen(kind="place", interaction=placed.interaction, label=placed.position,
                      markers=tuple(state.markers))
    if step is Step.HINT:
        return Screen(kind="hint", interaction=_current(slot).interaction)
    if step is Step.RATE:
        return Screen(kind="rate", interaction=_current(slot).interaction)
    if step is Step.ANSWER:
        return Screen(kind="question",
                      questions=state.unanswered)
    if step is Step.DONE:
        return Screen(kind="done")
    return _next_up(state)


def _current(slot: Slot | None) -> Slot:
    """The slot at the cursor while a trial runs, or is placed or rated: there is one."""
    assert slot is not None, "a trial runs, or is placed or rated, for the slot at the cursor"
    return slot


def hint_of(value: str) -> Hint | None:
    """The hint a choice of :data:`HINTS` stores (None: "it was fine", nothing to change)."""
    return None if value == NO_HINT else Hint(value)


def asked_question(question_id: str) -> Question:
    """The questionnaire's question ``question_id`` (an id the session or the draft holds)."""
    asked = question(question_id)
    assert asked is not None, f"{question_id!r} comes from the questionnaire"
    return asked


def answer_options(question_id: str) -> list[tuple[str, str]]:
    """(button text, stored value) of a question's answers: 1–5 with the paper's end labels, or
    the words themselves."""
    q = asked_question(question_id)
    if not q.numeric:
        return [(answer, answer) for answer in q.answers]
    return [(f"{i} – {text}" if not text.isdigit() else text, str(i))
            for i, text in enumerate(q.answers, start=1)]


def question_html(draft: Draft) -> str:
    """The question screen's heading: "Question 2 of 3" and the question as the participant reads
    it."""
    return (f'<div class="hl-count">Question {draft.number} of {len(questions())}</div>'
            + screen_text(asked_question(draft.question).text, kind="hl-question"))


class Choice:
    """Buttons of which the participant picks one (highlighted orange, changeable); a separate
    Confirm / Next button then acts on the choice."""

    def __init__(self, gui: viser.GuiApi, options: list[tuple[str, str]], chosen: str | None,
                 on_choose: Callable[[str], None]) -> None:
        self.buttons = {value: gui.add_button(text, color="orange" if value == chosen else "gray")
                        for text, value in options}
        for value, button in self.buttons.items():
            button.on_click(self._choosing(value, on_choose))

    @staticmethod
    def _choosing(value: str, on_choose: Callable[[str], None]) -> Callable[[object], None]:
        return lambda _: on_choose(value)

    def show(self, chosen: str | None) -> None:
        for value, button in self.buttons.items():
            button.color = "orange" if value == chosen else "gray"


class TabletClient:
    """One connected page. :meth:`show` redraws only when the screen changed; every input passes
    :meth:`_input` (settled, one at a time)."""

    def __init__(self, client: viser.ClientHandle, runner: SessionRunner,
                 redraw: Callable[[], None], settle_s: float = SETTLE_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.client, self.runner, self._redraw = client, runner, redraw
        self.screen: Screen | None = None
        self.settle = Settle(settle_s, clock)
        self._draft: Draft | None = None  # the questionnaire's choices before the last Next
        self._choice: Choice | None = None
        self._next: viser.GuiButtonHandle | None = None
        self._lock = threading.RLock()
        self._acting = threading.Lock()

    def show(self, screen: Screen) -> None:
        with self._lock:
            if screen == self.screen or self._acting.locked():
                return  # an action in progress redraws when it is done
            self.screen = screen
            self._draft = Draft(questions=screen.questions) if screen.kind == "question" else None
            self._draw()

    def _draw(self) -> None:
        screen, gui = self.screen, self.client.gui
        assert screen is not None, "a page is drawn once show has given it its screen"
        with self.client.atomic():
            gui.reset()
            gui.add_html(PAGE_STYLE)
            build = {"wait": self._wait, "pairs": self._pairs, "go": self._go, "back": self._back,
                     "place": self._place, "hint": self._hint, "rate": self._rate,
                     "question": self._question, "done": self._done, "unused": self._unused,
                     "pair": self._pair}
            build[screen.kind](gui, screen)
            # Inside atomic(): the window starts before the screen can reach the page (viser holds
            # the messages until the block ends), so no input answering this screen is judged
            # against the window of the screen before it.
            self.settle.restart()

    # -- the screens: each adds its handles and callbacks ----------------------------------------
    def _wait(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Please wait", screen.next_up or "The next handover is being "
                                                                  "prepared."))

    def _pairs(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Now: pairs of handovers",
                                 "The robot will now hand you the object twice in a row. After "
                                 "the second time, tell us whether it felt better, the same, or "
                                 "worse than the first.", "hl-question")
                     + '<div class="hl-count">Take the object when this screen tells you to.</div>')

    def _go(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Go!", "Take the object from the robot.", "hl-go") + audio_cue())

    def _back(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("One moment", "The robot is moving back."))

    def _done(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Thank you!", "The session is complete."))

    def _unused(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("This tablet is not in use",
                                 "Another page is open as the study's tablet. "
                                 "Please close this page.", "hl-unused"))

    def _pair(self, gui: viser.GuiApi, screen: Screen) -> None:
        gui.add_html(screen_text("Connect this tablet", "Type the code shown on the "
                                 "experimenter's screen.", "hl-unused"))
        code = gui.add_text("Code", "")
        connect = gui.add_button("Connect", color="green")
        refusal = gui.add_html("")

        def pair() -> None:
            why = self.runner.pair_tablet(self.client.client_id, code.value)
            refusal.content = "" if why is None else screen_text("", why)

        connect.on_click(lambda _: self._input(pair))

    def _place(self, gui: viser.GuiApi, screen: Screen) -> tuple[viser.GuiSliderHandle,
                                                                 viser.GuiButtonHandle]:
        gui.add_html(screen_text(f"Handover {screen.label}",
                                 "Drag the orange handle to where this handover belongs. "
                                 "Drop it on a number if it felt the same."))
        markers, label, interaction = list(screen.markers), screen.label, screen.interaction
        assert label is not None and interaction is not None, "screen_for names the handover"
        start = start_position(markers)
        # Confirm stays grey until the handle moves: the scale says so above the arrow, or one who
        # leaves it where it starts waits for a button that never lights up
        scale = gui.add_html(render_scale(markers, label, start, hint=MOVE_FIRST))
        slider = gui.add_slider("", min=0.0, max=1.0, step=0.001, initial_value=start)
        confirm = gui.add_button("Confirm", color="green", disabled=True)

        @slider.on_update
        def _(_: viser.GuiEvent) -> None:
            if self.settle.ready():  # a drag carried over from the screen before does not count
                confirm.disabled = False
            scale.content = render_scale(markers, label, slider.value,
                                         hint=MOVE_FIRST if confirm.disabled else "")

        def place() -> None:
            if confirm.disabled:
                return  # the handle has not moved: nothing to confirm
            landed = snap(slider.value, markers)
            self.runner.place(interaction,
                              position=None if landed else round(slider.value, 3),
                              equal_to=landed.interaction if landed else None)

        confirm.on_click(lambda _: self._input(place))
        return slider, confirm

    def _hint(self, gui: viser.GuiApi, screen: Screen) -> Choice:
        gui.add_html(screen_text("Should the robot do anything differently?",
                                 "Think of the handover you just had. Choose one, then tap "
                                 "Confirm.", "hl-question"))
        interaction = screen.interaction
        assert interaction is not None, "screen_for names the handover"
        return self._decide(gui, list(HINTS),
                            lambda value: self.runner.hint(interaction, hint_of(value)))

    def _rate(self, gui: viser.GuiApi, screen: Screen) -> Choice:
        gui.add_html(screen_text("Compared with the handover before it, this one felt …",
                                 kind="hl-question"))
        interaction = screen.interaction
        assert interaction is not None, "screen_for names the handover"
        return self._decide(gui, list(RATINGS),
                            lambda value: self.runner.rate(interaction, value))

    def _decide(self, gui: viser.GuiApi, options: list[tuple[str, str]],
                act: Callable[[str], None]) -> Choice:
        """One of ``options`` to choose (changeable), then Confirm, which acts on the choice: a
        tap on a choice alone records nothing."""
        chosen: list[str] = []

        def choose(value: str) -> None:
            chosen[:] = [value]
            choice.show(value)
            confirm.disabled = False

        def decide() -> None:
            if chosen:
                act(chosen[0])

        choice = Choice(gui, options, None, lambda value: self._input(lambda: choose(value)))
        confirm = gui.add_button("Confirm", color="green", disabled=True)
        confirm.on_click(lambda _: self._input(decide))
        return choice

    def _question(self, gui: viser.GuiApi, screen: Screen) -> Choice:
        draft = self._draft
        assert draft is not None, "show starts a draft with every question screen"
        if not draft.first:
            gui.add_button("‹ Back", color="dark").on_click(
                lambda _: self._input(self._previous_question))
        gui.add_html(question_html(draft))
        choice = Choice(gui, answer_options(draft.question), draft.choice,
                        lambda value: self._input(lambda: self._choose(value)))
        self._next = gui.add_button("Done" if draft.last else "Next", color="green",
                                    disabled=draft.choice is None)
        self._next.on_click(lambda _: self._input(self._forward))
        self._choice = choice
        return choice

    # -- the questionnaire's moves (on the page until the last Next) -----------------------------
    def _choose(self, value: str) -> None:
        draft, choice, next_button = self._draft, self._choice, self._next
        assert draft is not None and choice is not None and next_button is not None, \
            "chosen on a question screen, which has them"
        self._draft = draft.choose(value)
        choice.show(value)
        next_button.disabled = False

    def _previous_question(self) -> None:
        """The question before, with the choices made so far — this one's included (the draft as
        it is now: the one of when the screen was drawn had not this question's choice)."""
        draft = self._draft
        assert draft is not None, "Back is on a question screen, which has its draft"
        self._turn(draft.back())

    def _turn(self, draft: Draft) -> None:
        self._draft = draft
        with self._lock:
            self._draw()

    def _forward(self) -> None:
        draft = self._draft
        assert draft is not None, "Next is on a question screen, which has its draft"
        if draft.choice is None:
            return
        if not draft.last:
            self._turn(draft.next())
            return
        for question_id, value in draft.complete():
            try:
                self.runner.answer(question_id, value)
            except RefusedAction as exc:  # e.g. answered meanwhile by the simulated participant
                log.warning("tablet answer refused: %s", exc)

    # -- input ------------------------------------------------------------------------------------
    def _input(self, action: Callable[[], None]) -> None:
        """A participant's input: ignored while the screen settles or while the page's previous
        input is still being handled; a refusal (stale screen) is logged, not shown: the page is
        redrawn from the state anyway."""
        if not self.settle.ready() or not self._acting.acquire(blocking=False):
            log.info("tablet input ignored (screen shown < %.1f s ago or busy)",
                     self.settle.settle_s)
            return
        try:
            action()
        except RefusedAction as exc:
            log.warning("tablet action refused: %s", exc)
        finally:
            self._acting.release()
        self._redraw()


class Tablet:
    """The tablet server: one :class:`TabletClient` per open page; the paired one is the study's
    tablet (:class:`~app.session.pairing.TabletPairing`). ``source_of`` gives a page's remote
    address (:meth:`app.ui.guard.Guard.source_of`), ``browser_of`` its browser's id
    (:meth:`app.ui.guard.Guard.browser_of`); ``settle_s``: input is ignored for this long
    after each screen change, on ``clock`` (a test's own clock ends the window when it says so)."""

    def __init__(self, server: viser.ViserServer, runner: SessionRunner,
                 source_of: Callable[[int], str],
                 browser_of: Callable[[int], str | None] = lambda _: None,
                 settle_s: float = SETTLE_S, clock: Callable[[], float] = time.monotonic) -> None:
        self.server, self.runner, self.settle_s, self._clock = server, runner, settle_s, clock
        self._pages: dict[int, TabletClient] = {}  # in the order they connected
        self._source_of, self._browser_of = source_of, browser_of
        self.pairing = runner.attach_tablet()
        self._lock = threading.RLock()
        server.gui.configure_theme(show_logo=False, show_share_button=False, control_width="large")
        server.gui.main_panel.dock_left()
        server.gui.main_panel.set_width(4000)
        server.scene.configure_environment_map(hdri=None)
        server.on_client_connect(self._connect)
        server.on_client_disconnect(self._disconnect)
        runner.subscribe(self.refresh)

    def connected_count(self) -> int:
        """How many pages are open on the tablet port (exactly one during a session)."""
        with self._lock:
            return len(self._pages)

    def _connect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._pages[client.client_id] = TabletClient(client, self.runner, self.redraw,
                                                         self.settle_s, self._clock)
        self.runner.tablet_connected(client.client_id, self._source_of(client.client_id),
                                     self._browser_of(client.client_id))
        log.info("tablet page %d connected (%d open)", client.client_id, self.connected_count())
        self.redraw()

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._pages.pop(client.client_id, None)
        self.runner.tablet_closed(client.client_id)
        log.info("tablet page %d closed (%d open)", client.client_id, self.connected_count())
        self.redraw()

    def redraw(self) -> None:
        self.refresh(self.runner.view)

    def refresh(self, view: RunnerView) -> None:
        screen = screen_for(view)
        shown = {"tablet": screen, "unused": UNUSED, "pair": PAIR}
        with self._lock:
            for page_id, page in list(self._pages.items()):
                page.show(shown[self.pairing.role(page_id)])
