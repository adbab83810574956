"""The dashboard's "Enter for the participant": when the tablet cannot be used (it died, the
participant cannot hold it), the experimenter enters what the participant says — the placement on
the scale, the coactive hint (``[protocol] coactive``), the validation rating, an answer — and the
store records it as entered by the
experimenter on the participant's behalf (``Rater.EXPERIMENTER``), so the export tells it apart.

Each entry is its own deliberate button and is enabled only while the session waits for that kind
of entry; it names the handover (or question) it is for, and the runner refuses it if the session
has moved on meanwhile (e.g. the tablet answered first). The tablet's deliberate-answer rule holds
here too: the scale's slider starts where the tablet's handle does (never on an earlier marker) for
each handover to place, and "Store the placement" waits until the experimenter has moved it or
chosen an earlier handover it is the same as. The hint buttons are shown only in sessions with
coactive hints."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import viser

from app.protocol.errors import RefusedAction
from app.protocol.plan import Slot
from app.protocol.state import SessionState, Step
from app.session.runner import RunnerView, SessionRunner
from app.ui.scale_view import start_position
from app.ui.tablet import HINTS, RATINGS, answer_options, asked_question, hint_of
from session_store.vocabulary import Rater

#: The "same as" choice that means: a position on the scale, not an earlier marker.
NOT_EQUAL = "— (use the position)"


@dataclass
class OnBehalf:
    """The folder's widgets; :meth:`show` follows the session, the buttons act through ``act``."""

    what: viser.GuiMarkdownHandle
    position: viser.GuiSliderHandle
    same_as: viser.GuiDropdownHandle
    place: viser.GuiButtonHandle
    hints: list[viser.GuiButtonHandle]
    ratings: list[viser.GuiButtonHandle]
    answer: viser.GuiDropdownHandle
    store_answer: viser.GuiButtonHandle
    #: The interaction the slider was set for (None: none is being placed), and whether the
    #: experimenter has moved it since.
    placing: int | None = None
    moved: bool = False

    @classmethod
    def build(cls, gui: viser.GuiApi, runner: SessionRunner,
              act: Callable[[Callable[[], None]], None]) -> OnBehalf:
        gui.add_markdown("Only when the tablet cannot be used: enter what the participant tells "
                         "you. It is stored as entered by the experimenter for the participant.")
        entry = cls(
            what=gui.add_markdown(""),
            position=gui.add_slider("Scale: 0 Strongly Worse … 1 Strongly Better", min=0.0,
                                    max=1.0, step=0.01, initial_value=0.5),
            same_as=gui.add_dropdown("Or the same as", [NOT_EQUAL]),
            place=gui.add_button("Store the placement for the participant"),
            hints=[gui.add_button(f"They said: {text}") for text, _ in HINTS],
            ratings=[gui.add_button(f"Second felt: {text}") for text, _ in RATINGS],
            answer=gui.add_dropdown("Answer", ["—"]),
            store_answer=gui.add_button("Store the answer for the participant"),
        )
        by = Rater.EXPERIMENTER

        def place() -> None:
            state = _open_state(runner.view)
            if entry.same_as.value == NOT_EQUAL:
                runner.place(_slot(state).interaction, position=entry.position.value, by=by)
                return
            label = int(entry.same_as.value.split()[-1])  # as the tablet numbers the batch
            same = next((m.interaction for m in state.markers if m.label == label), None)
            if same is None:
                raise ValueError(f"handover {label} is not on the scale any more")
            runner.place(_slot(state).interaction, equal_to=same, by=by)

        def rate(value: str) -> None:
            runner.rate(_slot(_open_state(runner.view)).interaction, value, by=by)

        def hint(value: str) -> None:
            runner.hint(_slot(_open_state(runner.view)).interaction, hint_of(value), by=by)

        def entering(enter: Callable[[str], None], value: str) -> Callable[[object], None]:
            return lambda _: act(lambda: enter(value))

        def answer() -> None:
            question = _question(runner.view)
            labels = dict(answer_options(question))
            if entry.answer.value not in labels:
                raise ValueError("choose the participant's answer first")
            runner.answer(question, labels[entry.answer.value], by=by)

        def moved(event: viser.GuiEvent) -> None:
            if event.client is not None:  # the experimenter's hand, not show() setting it
                entry.moved = True
                entry.show(runner.view)

        entry.position.on_update(moved)
        entry.same_as.on_update(lambda event: None if event.client is None else
                                entry.show(runner.view))
        entry.place.on_click(lambda _: act(place))
        for button, (_, value) in zip(entry.hints, HINTS, strict=True):
            button.on_click(entering(hint, value))
        for button, (_, value) in zip(entry.ratings, RATINGS, strict=True):
            button.on_click(entering(rate, value))
        entry.store_answer.on_click(lambda _: act(answer))
        return entry

    def show(self, view: RunnerView) -> None:
        """Enable the entry the session waits for, and say which handover or question it is."""
        state = view.state
        step = None if state is None or state.paused else state.step
        self._start_placing(state if step is Step.PLACE else None)
        self.position.disabled = self.same_as.disabled = step is not Step.PLACE
        for button in self.hints:
            button.visible = state is not None and state.coactive
            button.disabled = step is not Step.HINT
        for button in self.ratings:
            button.disabled = step is not Step.RATE
        self.answer.disabled = self.store_answer.disabled = step is not Step.ANSWER
        placing = state if step is Step.PLACE else None
        markers = [] if placing is None else [f"handover {m.label}" for m in placing.markers]
        options = (NOT_EQUAL, *markers)
        if tuple(self.same_as.options) != options:
            self.same_as.options = options
            # viser 1.1.1 defines the value's setter apart from its getter, so mypy reads it as read-only
            self.same_as.value = NOT_EQUAL  # type: ignore[misc]
        self.place.disabled = step is not Step.PLACE or not (
            self.moved or self.same_as.value != NOT_EQUAL)
        if placing is not None:
            self.what.content = f"The participant places **handover {_slot(placing).position}**."
        elif step is Step.HINT:
            self.what.content = (f"After **handover {_slot(_open_state(view)).position}**: should the robot "
                                 "do anything differently? (the participant's hint)")
        elif step is Step.RATE:
            self.what.content = ("The participant compares the **second handover of the pair** "
                                 "with the first.")
        elif step is Step.ANSWER:
            asked = asked_question(_question(view))
            self.what.content = f"**{asked.id}**: {asked.text}"
        else:
            self.what.content = "Nothing to enter now."
        labels = tuple(text for text, _ in answer_options(_question(view))) \
            if step is Step.ANSWER else ("—",)
        if tuple(self.answer.options) != labels:
            self.answer.options = labels


    def _start_placing(self, placing: SessionState | None) -> None:
        """A new handover to place: the slider where the tablet's handle starts, untouched."""
        interaction = None if placing is None else _slot(placing).interaction
        if interaction == self.placing:
            return
        self.placing, self.moved = interaction, False
        if placing is not None:
            # viser 1.1.1 defines the value's setter apart from its getter, so mypy reads it as read-only
            self.position.value = start_position(placing.markers)  # type: ignore[misc]
            self.same_as.value = NOT_EQUAL  # type: ignore[misc]


def _question(view: RunnerView) -> str:
    """The first question not answered yet (the order the tablet asks them in)."""
    return _open_state(view).unanswered[0]


def _open_state(view: RunnerView) -> SessionState:
    """The open session's state; an entry that arrives once no session is open is refused."""
    if view.state is None:
        raise RefusedAction("no participant is open")
    return view.state


def _slot(state: SessionState) -> Slot:
    """The handover at the cursor, the one an entry is for."""
    if state.slot is None:
        raise RefusedAction("the session waits for no handover")
    return state.slot
