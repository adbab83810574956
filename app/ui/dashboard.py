"""The experimenter's dashboard: safety, study overview, participant, session control, entries for
the participant (:mod:`app.ui.on_behalf`), devices, live view and replay, a rehearsal's staged
faults, learner.

A client sees only a token field until it enters the dashboard token (kept with the study); a
browser in which it was entered before is let in without it (:class:`~app.ui.guard.TokenGate`). After
that its panels are rendered from the runner's published :class:`RunnerView` (a reload rebuilds them
from the session state). Safety first:

* **STOP ARM is pinned**: it lives in its own panel docked beside the main one, so it never scrolls
  away, and **Esc** triggers it too (a viser command with a hotkey; ignored while typing in a field).
  It is never disabled. After a stop, Start stays locked until **Re-arm** ("the scene is safe"), and
  the arm's status says "stopping" until the stop has completed, then "stopped".
* The physical e-stop is named beside it, and a lost connection covers the page with a banner
  saying so (:data:`~app.ui.style.DASHBOARD_OFFLINE_CSS`): this page cannot stop the arm then.
* Start is disabled, with the reason beside it, unless exactly one paired tablet is open.
* Every window is told how many dashboard windows are unlocked and from where; one of them controls
  the session, the others are view-only until the experimenter presses **Take control** on one
  (:mod:`app.session.windows`). STOP ARM works from every window.

Refusals are shown next to the controls (or the form field) they concern and cleared as soon as the
session moves on. With ``blind`` (double-blind validation) the θ and origin of validation trials are
not shown.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import viser
import viser.uplot

from app.learning.models import PosteriorSlice
from app.protocol.state import Step
from app.session.faults import StagedFault
from app.session.runner import RunnerView, SessionRunner
from app.session.windows import DashboardWindows
from app.ui.guard import TokenGate
from app.ui.live_view import STRIDE, LiveView
from app.ui.on_behalf import OnBehalf
from app.ui.participant_form import build_participant_form
from app.ui.replay import SPEEDS, Replay
from app.ui.status_text import (
    devices_markdown,
    learner_markdown,
    overview_markdown,
    progress_markdown,
    safety_markdown,
    start_blocker,
    status_line,
    tablet_markdown,
)
from app.ui.style import DASHBOARD_CSS, DASHBOARD_OFFLINE_CSS, STOP_LABEL, style_block
from robot_io.control.stages import current
from robot_io.errors import RobotIOError
from session_store.errors import StoreError

log = logging.getLogger(__name__)

#: The key that stops the arm (besides the pinned button).
STOP_KEY = "escape"
#: Width of the pinned safety panel [px].
SAFETY_WIDTH = 230
ESTOP_REMINDER = ("The **physical e-stop** (the red button on the teach pendant) stops the arm "
                  "whatever this page shows. Use it if this page does not answer.")
#: Why a view-only window's Start is locked.
VIEW_ONLY = "this window is view-only: press Take control to control the session from here"
#: The page marker the offline banner looks for.
LIVE_MARKER = '<span class="hl-live"></span>'

#: Colours of the posterior slices along a, δ and k.
SLICE_COLOURS = ("#1c7ed6", "#e8590c", "#2b8a3e")


def posterior_plot(gui: viser.GuiApi) -> viser.GuiUplotHandle:
    """The posterior utility along a, δ and k through θ* (eq. 13), each against its position in Θ
    (0 = lower bound, 1 = upper bound of Table I)."""
    series = [viser.uplot.Series(label="position in Θ")] + [
        viser.uplot.Series(label=f"u along {name}", stroke=colour, width=2)
        for name, colour in zip(("a", "δ", "k"), SLICE_COLOURS, strict=True)]
    return gui.add_uplot(tuple(np.zeros(1) for _ in series), tuple(series),
                         scales={"x": viser.uplot.Scale(time=False, auto=True)},
                         legend=viser.uplot.Legend(show=True), aspect=2.0)


def posterior_data(slices: list[PosteriorSlice]) -> tuple[np.ndarray, ...]:
    """uPlot columns: the common position in Θ, then the posterior mean along each parameter."""
    position = np.linspace(0.0, 1.0, len(slices[0].values))
    return (position, *(np.asarray(s.mean) for s in slices))


def gate_buttons(gui: viser.GuiApi) -> dict[str, viser.GuiButtonHandle]:
    """A button for each confirmation of the cycle (its table's gates, in order): the last one, Go,
    is the participant's cue and green."""
    gated = current().gated
    return {row.name: gui.add_button(row.gate.button, color="green" if row is gated[-1] else "blue")
            for row in gated if row.gate is not None}


def error_key(view: RunnerView) -> tuple:
    """What a refusal was about: when any of it changes, the refusal is no longer current."""
    tablet = view.tablet
    return (view.code, view.step, view.state.paused if view.state else None, view.stop,
            view.arm_fault, view.waiting_for, tablet.ready if tablet else None, view.auto)


@dataclass
class Controls:
    start: viser.GuiButtonHandle
    start_why: viser.GuiMarkdownHandle
    gates: dict[str, viser.GuiButtonHandle]  # one per gated stage of the cycle: Object loaded, Go
    abort: viser.GuiButtonHandle
    recover: viser.GuiButtonHandle
    pause: viser.GuiButtonHandle
    resume: viser.GuiButtonHandle
    end: viser.GuiButtonHandle
    auto: viser.GuiCheckboxHandle
    #: The session's "simulated participant" setting the box was last set to (None: not yet).
    shown_auto: bool | None = None

    def enable_for(self, view: RunnerView, controlling: bool) -> None:
        """Enable what the session allows now; nothing in a view-only window."""
        step, state = view.step, view.state
        paused = state is not None and state.paused
        blocker = start_blocker(view) if controlling else VIEW_ONLY
        self.start.disabled = step is not Step.READY or blocker is not None
        self.start_why.content = f"Start is locked: {blocker}." if blocker and state else ""
        for stage, button in self.gates.items():
            button.disabled = view.waiting_for != stage or not controlling
        self.abort.disabled = step is not Step.RUNNING
        self.recover.disabled = view.arm_fault is None or step is Step.RUNNING
        self.pause.disabled = state is None or paused or step in (Step.RUNNING, Step.DONE)
        self.resume.disabled = not paused
        self.end.disabled = state is None or step is Step.RUNNING
        if not controlling:
            for control in (self.abort, self.recover, self.pause, self.resume, self.end):
                control.disabled = True
        self.auto.disabled = not controlling
        self._show_auto(view.auto)

    def _show_auto(self, auto: bool) -> None:
        """Set the box when the session's setting changed, not on every refresh: viser holds a
        click's value in the box before the box's callback reads it to switch the session, and a
        refresh for anything else in between would set the box back and lose the click."""
        if auto != self.shown_auto:
            self.shown_auto = auto
            # viser 1.1.1 defines the value's setter apart from its getter, so mypy reads it as read-only
            self.auto.value = auto  # type: ignore[misc]


@dataclass
class Safety:
    """The pinned panel: STOP ARM (and its key), Re-arm, the arm's stop state, the e-stop."""

    stop: viser.GuiButtonHandle
    rearm: viser.GuiButtonHandle
    state: viser.GuiMarkdownHandle

    def show(self, view: RunnerView, controlling: bool) -> None:
        self.rearm.disabled = view.stop != "stopped" or not controlling
        self.state.content = safety_markdown(view)


class DashboardClient:
    """One experimenter's browser."""

    def __init__(self, client: viser.ClientHandle, runner: SessionRunner, gate: TokenGate,
                 windows: DashboardWindows, address: str, on_windows: Callable[[], None],
                 listed: Callable[[], bool], blind: bool = False) -> None:
        self.client, self.runner, self.gate, self.blind = client, runner, gate, blind
        self.windows, self.address, self._on_windows = windows, address, on_windows
        #: whether viser still lists the page: it closes a page's connection before it tells us
        #: (``_disconnect``), and drops (with a warning) what is drawn for it meanwhile
        self._listed = listed
        self.live: LiveView | None = None
        self.replay: Replay | None = None
        self._code: str | None = "-"
        self._error_key: tuple | None = None
        self._lock = threading.Lock()  # over every change of this page's panels, and its close
        self._closed = False  # the page has gone: nothing is drawn for it (a token answered later
        #                       unlocks nothing then)
        self._replays_ended = False  # the page or the server closes: no replay starts
        if gate.recognised(client.client_id):  # unlocked in this browser before
            self.refresh(runner.view, rebuild=True)
        else:
            self._locked_screen()

    # -- access -----------------------------------------------------------------------------------
    def _locked_screen(self) -> None:
        gui = self.client.gui
        gui.add_html(style_block(DASHBOARD_CSS + DASHBOARD_OFFLINE_CSS) + LIVE_MARKER)
        gui.add_markdown("### handover-lab dashboard\nEnter the dashboard token (printed by "
                         "`handover serve` and kept in the study folder).")
        field = gui.add_text("Token", "")
        unlock = gui.add_button("Unlock")
        error = gui.add_markdown("")

        def answered(refusal: str | None) -> None:
            if refusal is None:
                self.refresh(self.runner.view, rebuild=True)
            else:
                error.content = f"⚠ {refusal}"

        @unlock.on_click
        def _(_: viser.GuiEvent) -> None:
            waiting = self.gate.attempt(self.client.client_id, field.value.strip(), answered)
            if waiting is not None:
                error.content = waiting

    # -- panels -----------------------------------------------------------------------------------
    def refresh(self, view: RunnerView, rebuild: bool = False) -> None:
        """Show ``view``; ``rebuild``: build the panels anew (the first build is the unlock: the
        window is then one of the dashboard windows, and every window is told)."""
        with self._lock:
            if self._closed or (self.live is None and not rebuild):
                return  # gone, or still locked
            unlocking = self.live is None
            if unlocking:
                self.windows.opened(self.client.client_id, self.address)
            if rebuild or view.code != self._code:
                self._build(view)
            window = self.windows.status(self.client.client_id)
            self.window_line.content = window.words()
            self.take_control.visible = not window.controlling
            self.safety.show(view, window.controlling)
            self.status.content = status_line(view) if window.controlling else \
                f"**View-only window** · {status_line(view)}"
            self.tablet.content = tablet_markdown(view)
            self.overview.content = overview_markdown(view.overview)
            self.devices.content = devices_markdown(view)
            if view.state is not None:
                self.progress.content = progress_markdown(view)
                self.learner.content = learner_markdown(view, self.blind)
                self.controls.enable_for(view, window.controlling)
                self.on_behalf.show(view)
                self._trials_for_replay(view)
                if view.posterior:
                    self.posterior.data = posterior_data(view.posterior)
            if self._error_key is not None and error_key(view) != self._error_key:
                self._show_error(None)  # the refusal is no longer true
        if unlocking:
            self._on_windows()

    def tick(self) -> None:
        """The live view's next frame (the ticker's thread), unless a replay draws or the page left."""
        with self._lock:
            if (not self._closed and self.live is not None and self._listed()
                    and (self.replay is None or not self.replay.running)):
                self.live.update(self.runner.live(STRIDE)[1])

    def close(self) -> None:
        """The page has gone: no more refreshes (a token's answer that waited unlocks nothing),
        frames or replays for it; a running replay's thread is joined."""
        with self._lock:
            self._closed = True
        self.end_replays()

    def end_replays(self) -> None:
        """End this page's replay and wait for its thread; none starts after it (the page's close,
        and the server's before the session closes)."""
        with self._lock:
            self._replays_ended, replay = True, self.replay
        if replay is not None:
            replay.stop()

    def _build(self, view: RunnerView) -> None:
        gui = self.client.gui
        self._code = view.code
        self.cancel_replay()
        with self.client.atomic():
            gui.reset()
            self.client.scene.reset()
            gui.add_html(style_block(DASHBOARD_CSS + DASHBOARD_OFFLINE_CSS) + LIVE_MARKER)
            self.safety = self._safety(gui)
            self.status = gui.add_markdown("")
            self.window_line = gui.add_markdown("")
            self.take_control = gui.add_button("Take control", color="violet", visible=False)
            self.take_control.on_click(lambda _: self._act(self._take_control, control=False))
            self.error = gui.add_markdown("")
            with gui.add_folder("Study"):
                self.overview = gui.add_markdown("")
                build_participant_form(gui, view, self.runner, self._act)
            if view.state is not None:
                with gui.add_folder("Session"):
                    self.progress = gui.add_markdown("")
                    self.controls = self._controls(gui)
            self.tablet = gui.add_markdown("")
            with gui.add_folder("Devices"):
                self.devices = gui.add_markdown("")
            with gui.add_folder("Coupling signals (live)"):
                self.live = LiveView(self.client, self.runner.scene_config())
            if view.state is not None:
                with gui.add_folder("Enter for the participant", expand_by_default=False):
                    self.on_behalf = OnBehalf.build(gui, self.runner, self._act)
            if view.rehearsal:
                with gui.add_folder("Rehearse a fault", expand_by_default=False):
                    self._fault_controls(gui, view)
            if view.state is not None:
                with gui.add_folder("Replay a stored trial", expand_by_default=False):
                    self._replay_controls(gui)
                with gui.add_folder("Learner", expand_by_default=False):
                    self.learner = gui.add_markdown("")
                    self.posterior = posterior_plot(gui)

    def _safety(self, gui: viser.GuiApi) -> Safety:
        """The pinned safety panel, and Esc as STOP ARM."""
        panel = gui.add_panel()
        with panel.add_tab("Safety", viser.Icon.HAND_STOP):
            gui.add_html('<span class="hl-safety"></span>')
            safety = Safety(stop=gui.add_button(STOP_LABEL, color="red", icon=viser.Icon.HAND_STOP),
                            rearm=gui.add_button("Re-arm (scene is safe)", color="teal",
                                                 disabled=True),
                            state=gui.add_markdown(""))
            gui.add_markdown(f"**Esc** also stops the arm.\n\n{ESTOP_REMINDER}")
        panel.dock_right()
        panel.set_width(SAFETY_WIDTH)
        safety.stop.on_click(lambda _: self._act(self.runner.stop, control=False))
        safety.rearm.on_click(lambda _: self._act(self.runner.rearm))
        command = gui.add_command(STOP_LABEL, description="Stop the arm now", hotkey="escape",
                                  icon=viser.Icon.HAND_STOP)
        command.on_trigger(lambda _: self._act(self.runner.stop, control=False))
        return safety

    def _controls(self, gui: viser.GuiApi) -> Controls:
        controls = Controls(
            start=gui.add_button("Start trial", color="green", icon=viser.Icon.PLAYER_PLAY),
            start_why=gui.add_markdown(""),
            gates=gate_buttons(gui),
            abort=gui.add_button("Abort trial", color="orange"),
            recover=gui.add_button("Recover arm (cause inspected)", color="yellow"),
            pause=gui.add_button("Pause session"),
            resume=gui.add_button("Resume session"),
            end=gui.add_button("End session", color="gray"),
            auto=gui.add_checkbox("Simulated participant rates", False),
        )
        controls.start.on_click(lambda _: self._act(self.runner.start_trial))
        for stage, button in controls.gates.items():
            button.on_click(self._confirming(stage))
        controls.abort.on_click(lambda _: self._act(self.runner.abort_trial))
        controls.recover.on_click(lambda _: self._act(self.runner.recover_arm))
        controls.pause.on_click(lambda _: self._act(self.runner.pause))
        controls.resume.on_click(lambda _: self._act(self.runner.resume))
        controls.end.on_click(lambda _: self._act(self.runner.end_session))
        controls.auto.on_update(lambda event: None if event.client is None else self._act(
            lambda: self.runner.set_auto(controls.auto.value)))  # not when refresh sets it
        return controls

    def _fault_controls(self, gui: viser.GuiApi, view: RunnerView) -> None:
        """A rehearsal's staged faults: one button each, and the participant who does not take
        the object (the rig's reaction is what is rehearsed)."""
        gui.add_markdown("Stage a fault during a trial to see the rig handle it.")
        for fault in StagedFault:
            button = gui.add_button(fault.value, color="orange")
            button.on_click(self._staging(fault))
        refuse = gui.add_checkbox("The participant does not take the object", view.refusing_object)
        refuse.on_update(lambda event: None if event.client is None else self._act(
            lambda: self.runner.refuse_object(refuse.value)))

    def _staging(self, fault: StagedFault) -> Callable[[object], None]:
        return lambda _: self._act(lambda: self.runner.stage_fault(fault))

    def _confirming(self, stage: str) -> Callable[[object], None]:
        return lambda _: self._act(lambda: self.runner.confirm(stage))

    # -- replay -----------------------------------------------------------------------------------
    def _replay_controls(self, gui: viser.GuiApi) -> None:
        self.replay_trial = gui.add_dropdown("Trial", ["—"])
        self.replay_speed = gui.add_dropdown("Speed", list(SPEEDS), initial_value="1×")
        play = gui.add_button("Replay", icon=viser.Icon.PLAYER_PLAY)
        stop = gui.add_button("Stop replay")
        self.replay_status = gui.add_markdown("")
        play.on_click(lambda _: self._act(self._start_replay, control=False))  # this window's view
        stop.on_click(lambda _: self.cancel_replay())

    def _trials_for_replay(self, view: RunnerView) -> None:
        options = [f"trial {t.trial_index} · handover {t.interaction} · {t.outcome.value}"
                   for t in view.trials if t.outcome is not None] or ["—"]
        if tuple(options) != tuple(self.replay_trial.options):
            self.replay_trial.options = options
            # viser 1.1.1 defines the value's setter apart from its getter, so mypy reads it as read-only
            self.replay_trial.value = options[-1]  # type: ignore[misc]

    def _start_replay(self) -> None:
        choice = self.replay_trial.value
        if not choice.startswith("trial "):
            raise ValueError("no stored trial to replay yet")
        trial_index = int(choice.split()[1])
        rows = self.runner.trial_rows(trial_index)
        self.cancel_replay()
        with self._lock:
            if self._replays_ended:
                raise ValueError("the dashboard is closing: no replay")
            live = self.live
            assert live is not None, "the replay's controls are built with the live view"
            self.replay_status.content = (f"replaying trial {trial_index} at "
                                          f"{self.replay_speed.value}")
            self.replay = Replay(lambda rows: self._replay_frame(live, rows), rows,
                                 SPEEDS[self.replay_speed.value],
                                 busy=lambda: self.runner.view.step is Step.RUNNING,
                                 on_end=self._replay_ended)

    def _replay_frame(self, live: LiveView, rows: dict[str, np.ndarray]) -> None:
        """A replay's frame (its thread), drawn while the page is open and still shows ``live``."""
        with self._lock:
            if not self._closed and self.live is live and self._listed():
                live.draw(rows)

    def _replay_ended(self, why: str) -> None:
        """The replay's last frame stays until the live view has new rows (the next trial)."""
        with self._lock:
            if not self._closed and self._listed():
                self.replay_status.content = why

    def cancel_replay(self) -> None:
        if self.replay is not None:
            self.replay.cancel()

    # -- actions ----------------------------------------------------------------------------------
    def _take_control(self) -> None:
        self.windows.take(self.client.client_id)
        self._on_windows()

    def _act(self, action: Callable[[], object], control: bool = True) -> None:
        """Run an experimenter's action (``control``: one that controls the session, refused in a
        view-only window; STOP ARM is none); show why it was refused, next to the controls."""
        try:
            if control:
                self.windows.require_control(self.client.client_id)
            action()
            self._show_error(None)
        except (StoreError, RobotIOError, ValueError) as exc:
            log.warning("dashboard action refused: %s", exc)
            self._show_error(str(exc))

    def _show_error(self, text: str | None) -> None:
        self._error_key = None if text is None else error_key(self.runner.view)
        self.error.content = "" if text is None else f"⚠ **{text}**"


class Dashboard:
    """The dashboard server: token-gated clients, refreshed on every change and ticked for the
    live view. ``blind``: double-blind validation (see the module's docstring)."""

    def __init__(self, server: viser.ViserServer, runner: SessionRunner, gate: TokenGate,
                 source_of: Callable[[int], str], blind: bool = False) -> None:
        self.server, self.runner, self.gate, self.blind = server, runner, gate, blind
        self.source_of = source_of
        self.clients: dict[int, DashboardClient] = {}
        self.windows = DashboardWindows()
        self._replays_ended = False  # the server closes: no page starts a replay
        server.gui.configure_theme(show_logo=False, show_share_button=False, control_width="large")
        server.gui.main_panel.dock_right()
        server.gui.main_panel.set_width(520)
        server.on_client_connect(self._connect)
        server.on_client_disconnect(self._disconnect)
        runner.subscribe(self.refresh)

    def _connect(self, client: viser.ClientHandle) -> None:
        client.scene.configure_environment_map(hdri=None)
        self.clients[client.client_id] = DashboardClient(
            client, self.runner, self.gate, self.windows, self.source_of(client.client_id),
            self._windows_changed, lambda: client.client_id in self.server.get_clients(),
            self.blind)
        if self._replays_ended:  # a page that came while the server closes
            self.clients[client.client_id].end_replays()

    def _disconnect(self, client: viser.ClientHandle) -> None:
        page = self.clients.pop(client.client_id, None)
        if page is not None:
            page.close()
        self.windows.closed(client.client_id)
        if page is not None:
            self._windows_changed()

    def _windows_changed(self) -> None:
        """Every window shows the windows open and which one controls."""
        self.refresh(self.runner.view)

    def refresh(self, view: RunnerView) -> None:
        for client in list(self.clients.values()):
            client.refresh(view)

    def tick(self) -> None:
        for client in list(self.clients.values()):
            client.tick()

    def end_replays(self) -> None:
        """Every page's replay ended and its thread joined; none starts after it (the server's
        close, before the session's)."""
        self._replays_ended = True
        for client in list(self.clients.values()):
            client.end_replays()

    def close_pages(self) -> None:
        """Nothing more is drawn on any page (the server's close, after the session's and before
        viser stops: its stop closes every connection first, and one page's disconnect would
        refresh the others)."""
        for client in list(self.clients.values()):
            client.close()
