"""The experimenter's dashboard: participant, progress, trial control, devices, learner, live view.

A client sees only a token field until it enters the token printed by ``handover serve``. After that
its panels are rendered from the runner's published :class:`RunnerView` (a reload rebuilds them from
the session state), and every refused action is shown with the engine's reason. Stop is never
disabled: it stops the arm whatever else is going on.
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
from app.session.runner import RunnerView, SessionRunner
from app.ui.guard import TokenGate
from app.ui.live_view import STRIDE, LiveView
from app.ui.style import DASHBOARD_CSS, style_block
from robot_io.errors import RobotIOError
from robot_io.simulated_hand import Scenario
from robot_io.stages import Stage
from session_store.errors import StoreError

log = logging.getLogger(__name__)

NEXT: dict[Step, str] = {
    Step.PLAN: "the learner chooses the next θ; then Start trial",
    Step.READY: "press Start trial when the participant is ready",
    Step.RUNNING: "the handover cycle runs (Abort repeats it later; Stop stops the arm)",
    Step.PLACE: "the participant places the handover on the tablet's scale",
    Step.RATE: "the participant rates this handover against the previous one",
    Step.ANSWER: "the participant answers the questionnaire on the tablet",
    Step.DONE: "the session is complete: close the server (Ctrl-C) and export",
}


def progress_markdown(view: RunnerView) -> str:
    """Where the protocol stands and what comes next."""
    state = view.state
    if state is None:
        return "No participant open. Create or resume one above."
    slot = state.slot
    lines = [f"**{view.code}** · {view.scenario.value} · {state.completed} of "
             f"{view.interactions} handovers completed"]
    if slot is not None and state.step is not Step.ANSWER:
        attempt = state.attempts.get(slot.interaction, 0) + (state.step in (Step.PLAN, Step.READY))
        lines.append(f"phase **{slot.phase.value}** · batch {slot.batch} · handover "
                     f"{slot.position} of {slot.batch_size} · interaction {slot.interaction} · "
                     f"attempt {attempt}")
    elif state.step is Step.ANSWER:
        lines.append(f"phase **questionnaire** · {len(state.answers)} of 3 answered")
    if state.step is Step.RUNNING:
        lines.append(cycle_markdown(view))
    status = "**paused**" if state.paused else f"waiting for **{state.step.value}**"
    if view.preparing:
        status = "**preparing** (the learner is fitting)"
    lines.append(f"{status} — next: {NEXT[state.step]}")
    return "  \n".join(lines)


#: The handover cycle as the dashboard draws it, and what each stage waits for.
CYCLE = (Stage.PREPARE, Stage.LOADED, Stage.READY, Stage.GO, Stage.REACH, Stage.HOLD,
         Stage.RELEASE, Stage.RETRACT, Stage.DONE)
WAITING_TEXT = {"loaded": "load the object into the gripper, then press **Object loaded**",
                "go": "the participant's hand rests at the start: press **Go**"}


def cycle_markdown(view: RunnerView) -> str:
    """The running trial's stage within the cycle, the current one in bold, and what it waits for."""
    stage = view.stage
    shown = [f"**[{s.value}]**" if s is stage else s.value for s in CYCLE]
    if stage is Stage.NOT_TAKEN:
        shown[CYCLE.index(Stage.RELEASE)] = "**[not taken]**"
    line = "cycle: " + " → ".join(shown)
    if view.waiting_for is not None:
        line += f"  \n⏳ {WAITING_TEXT[view.waiting_for]}"
    if view.ready_wait and stage in (Stage.LOADED, Stage.PREPARE):
        line += f"  \n⏳ not ready: {view.ready_wait}"
    return line


def devices_markdown(view: RunnerView) -> str:
    def line(name: str, text: str, fault: str | None) -> str:
        return f"- **{name}**: {text}" + (f" — ⚠ **{fault}**" if fault else "")
    rig = ["- rehearsal: stand-in UR controller and simulated hand (no hardware)"] if view.rehearsal \
        else []
    return "\n".join([*rig, line("arm", view.arm, view.arm_fault), line("hand", view.hand, None),
                      line("gripper", view.gripper, None),
                      line("learner", view.learner, view.learner_fault),
                      "", "Recent events:", *[f"- {m}" for m in view.messages]])


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


def learner_markdown(view: RunnerView, rows: int = 10) -> str:
    """θ* after each learner update and the θ of the latest attempts (the posterior slices are
    drawn below it)."""
    star = view.theta_star[-1] if view.theta_star else None
    head = (f"θ* (best so far): **a {star.a:.2f}, δ {star.delta:.2f}, k {star.k:.2f}** after "
            f"interaction {star.after_interaction}" if star else "θ*: none yet")
    table = ["| trial | int. | phase | a | δ | k | origin | outcome |",
             "|---|---|---|---|---|---|---|---|"]
    table += [f"| {t.trial_index} | {t.interaction} | {t.phase.value} | {t.theta_a:.2f} | "
              f"{t.theta_delta:.2f} | {t.theta_k:.2f} | {t.origin.value} | "
              f"{t.outcome.value if t.outcome else 'running'} |" for t in view.trials[-rows:]]
    history = ", ".join(f"({s.a:.1f}, {s.delta:.2f}, {s.k:.1f})" for s in view.theta_star[-6:])
    return "\n".join([head, "", f"θ* history (latest 6): {history or '—'}", "", *table])


@dataclass
class Controls:
    start: viser.GuiButtonHandle
    loaded: viser.GuiButtonHandle
    go: viser.GuiButtonHandle
    abort: viser.GuiButtonHandle
    stop: viser.GuiButtonHandle
    recover: viser.GuiButtonHandle
    pause: viser.GuiButtonHandle
    resume: viser.GuiButtonHandle
    auto: viser.GuiCheckboxHandle

    def enable_for(self, view: RunnerView) -> None:
        step, state = view.step, view.state
        paused = state is not None and state.paused
        self.start.disabled = step is not Step.READY or paused
        self.loaded.disabled = view.waiting_for != "loaded"
        self.go.disabled = view.waiting_for != "go"
        self.abort.disabled = step is not Step.RUNNING
        self.recover.disabled = view.arm_fault is None or step is Step.RUNNING
        self.pause.disabled = state is None or paused or step in (Step.RUNNING, Step.DONE)
        self.resume.disabled = not paused
        self.auto.value = view.auto


class DashboardClient:
    """One experimenter's browser."""

    def __init__(self, client: viser.ClientHandle, runner: SessionRunner, gate: TokenGate) -> None:
        self.client, self.runner, self.gate = client, runner, gate
        self.live: LiveView | None = None
        self._code: str | None = "-"
        self._lock = threading.Lock()
        self._locked_screen()

    # -- access -----------------------------------------------------------------------------------
    def _locked_screen(self) -> None:
        gui = self.client.gui
        gui.add_markdown("### handover-lab dashboard\nEnter the access token that "
                         "`handover serve` printed.")
        field = gui.add_text("Token", "")
        unlock = gui.add_button("Unlock")
        error = gui.add_markdown("")

        @unlock.on_click
        def _(_: viser.GuiEvent) -> None:
            refusal = self.gate.attempt(self.client.client_id, field.value.strip())
            if refusal is None:
                self.refresh(self.runner.view, rebuild=True)
            else:
                error.content = f"⚠ {refusal}"

    # -- panels -----------------------------------------------------------------------------------
    def refresh(self, view: RunnerView, rebuild: bool = False) -> None:
        with self._lock:
            if self.live is None and not rebuild:
                return  # still locked
            if rebuild or view.code != self._code:
                self._build(view)
            self.progress.content = progress_markdown(view)
            self.devices.content = devices_markdown(view)
            self.learner.content = learner_markdown(view)
            if view.posterior:
                self.posterior.data = posterior_data(view.posterior)
            self.controls.enable_for(view)

    def tick(self) -> None:
        if self.live is not None:
            self.live.update(self.runner.live(STRIDE)[1])

    def _build(self, view: RunnerView) -> None:
        gui = self.client.gui
        self._code = view.code
        with self.client.atomic():
            gui.reset()
            self.client.scene.reset()
            gui.add_html(style_block(DASHBOARD_CSS))
            with gui.add_folder("Participant"):
                self._participant(gui, view)
            with gui.add_folder("Session"):
                self.progress = gui.add_markdown("")
                self.controls = self._controls(gui)
                self.error = gui.add_markdown("")
            with gui.add_folder("Devices"):
                self.devices = gui.add_markdown("")
            with gui.add_folder("Coupling signals (live)"):
                self.live = LiveView(self.client, self.runner.scene_config())
            with gui.add_folder("Learner", expand_by_default=False):
                self.learner = gui.add_markdown("")
                self.posterior = posterior_plot(gui)

    def _participant(self, gui: viser.GuiApi, view: RunnerView) -> None:
        if view.code is not None:
            gui.add_markdown(f"**{view.code}** ({view.scenario.value})")
            return
        known = self.runner.codes()
        gui.add_markdown("Existing: " + (", ".join(known) if known else "none") +
                         ". A known code resumes its session.")
        code = gui.add_text("Code", "")
        scenario = gui.add_dropdown("Scenario", [s.value for s in Scenario],
                                    initial_value=Scenario.PERTURBED.value)
        seed = gui.add_number("Seed", 0, step=1)
        rig_change = gui.add_checkbox("Confirm a rig change (resume on other devices)", False)
        open_button = gui.add_button("Create or resume")
        open_button.on_click(lambda _: self._act(lambda: self.runner.open(
            code.value.strip(), Scenario(scenario.value), int(seed.value),
            confirm_rig_change=rig_change.value)))

    def _controls(self, gui: viser.GuiApi) -> Controls:
        controls = Controls(
            start=gui.add_button("Start trial", color="green", icon=viser.Icon.PLAYER_PLAY),
            loaded=gui.add_button("Object loaded", color="blue"),
            go=gui.add_button("Go", color="green"),
            abort=gui.add_button("Abort trial", color="orange"),
            stop=gui.add_button("STOP ARM", color="red", icon=viser.Icon.HAND_STOP),
            recover=gui.add_button("Recover arm (cause inspected)", color="yellow"),
            pause=gui.add_button("Pause session"),
            resume=gui.add_button("Resume session"),
            auto=gui.add_checkbox("Simulated participant rates", False),
        )
        controls.start.on_click(lambda _: self._act(self.runner.start_trial))
        controls.loaded.on_click(lambda _: self._act(self.runner.object_loaded))
        controls.go.on_click(lambda _: self._act(self.runner.go))
        controls.abort.on_click(lambda _: self._act(self.runner.abort_trial))
        controls.stop.on_click(lambda _: self._act(self.runner.stop))
        controls.recover.on_click(lambda _: self._act(self.runner.recover_arm))
        controls.pause.on_click(lambda _: self._act(self.runner.pause))
        controls.resume.on_click(lambda _: self._act(self.runner.resume))
        controls.auto.on_update(lambda _: self._act(
            lambda: self.runner.set_auto(controls.auto.value)))
        return controls

    def _act(self, action: Callable[[], None]) -> None:
        """Run an experimenter's action; show why it was refused."""
        try:
            action()
            self.error.content = ""
        except (StoreError, RobotIOError, ValueError) as exc:
            log.warning("dashboard action refused: %s", exc)
            self.error.content = f"⚠ **{exc}**"


class Dashboard:
    """The dashboard server: token-gated clients, refreshed on every change and ticked for the
    live view."""

    def __init__(self, server: viser.ViserServer, runner: SessionRunner, gate: TokenGate) -> None:
        self.server, self.runner, self.gate = server, runner, gate
        self.clients: dict[int, DashboardClient] = {}
        server.gui.configure_theme(show_logo=False, show_share_button=False, control_width="large")
        server.gui.main_panel.dock_right()
        server.gui.main_panel.set_width(520)
        server.on_client_connect(self._connect)
        server.on_client_disconnect(lambda client: self.clients.pop(client.client_id, None))
        runner.subscribe(self.refresh)

    def _connect(self, client: viser.ClientHandle) -> None:
        client.scene.configure_environment_map(hdri=None)
        self.clients[client.client_id] = DashboardClient(client, self.runner, self.gate)

    def refresh(self, view: RunnerView) -> None:
        for client in list(self.clients.values()):
            client.refresh(view)

    def tick(self) -> None:
        for client in list(self.clients.values()):
            client.tick()
