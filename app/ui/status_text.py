"""The dashboard's words: what the session waits for, where the protocol stands, the devices, the
study overview — in the experimenter's language, every count 1-based. Pure: a view in, Markdown out.

Double-blind validation (``blind``): the θ and the origin of validation trials are not shown, so the
experimenter cannot tell which trial of a pair is the learned θ*.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from app.protocol.design import PlanStatus
from app.protocol.entries import not_used_words
from app.protocol.learning_words import stop_headline
from app.protocol.state import SessionState, Step
from app.session.overview import ParticipantSummary, SessionStatus
from app.session.runner import END_REASON, RunnerView
from app.ui.stage_words import before_ready, cycle_line, instead_of, stage_name, stage_words
from robot_io.control.stages import current
from session_store.vocabulary import Phase, questions

PHASE_WORDS = {Phase.INITIAL: "Initial handovers", Phase.LEARNING: "Learning batch",
               Phase.BEST: "Handover with the learned best", Phase.VALIDATION: "Validation pair"}


def _halted(view: RunnerView) -> tuple[str, str] | None:
    """The states in which nothing goes on, in two phrasings: why Start trial is locked, and the
    status line (None: none of them)."""
    state = view.state
    if state is None:
        return ("no participant is open",
                "No participant open — create or resume one under **Study**.")
    if view.stop == "stopping":
        return "the arm is stopping", "**Stopping the arm …**"
    if view.stop == "stopped":
        return ("the arm was stopped: make sure the scene is safe, then press Re-arm",
                "**Arm stopped** — make sure the scene is safe, then press **Re-arm**.")
    if state.paused:
        return ("the session is paused: press Resume session",
                "**Paused** — press **Resume session** to continue.")
    return None


def start_blocker(view: RunnerView) -> str | None:
    """Why Start trial cannot be pressed now (None: it can)."""
    if (halted := _halted(view)) is not None:
        return halted[0]
    if view.tablet_required and view.tablet is not None and view.tablet.blocker():
        return view.tablet.blocker()
    if view.arm_fault:
        return "the arm has a fault: inspect it, then press Recover arm"
    return None  # otherwise the status line says what the session waits for


def status_line(view: RunnerView) -> str:
    """One line: what the session waits for and what to do, e.g. "Paused — press Resume"; led by
    what the experimenter must notice about the tablet (a take-over, wrong pairing codes), then by
    an answer not used (two at once) and news of the protocol (learning stopped early), until the
    next trial."""
    alert = view.tablet.alert() if view.tablet is not None else None
    line = _status(view)
    news = _news(view)
    if news:
        line = f"**{news}.** · {line}"
    not_used = view.state.not_used if view.state is not None else None
    if not_used is not None:
        line = f"⚠ **{not_used_words(not_used)}.** · {line}"
    return f"⚠ **{alert}** · {line}" if alert else line


def _news(view: RunnerView) -> str | None:
    """Learning stopped early, between the stop and the next trial (then the Session panel keeps
    saying so)."""
    state = view.state
    if state is None or state.step not in (Step.PLAN, Step.READY) or state.stopped_after is None:
        return None
    if any(interaction > state.stopped_after for interaction in state.completed_trial):
        return None
    return stop_headline(state)


def _status(view: RunnerView) -> str:
    if (halted := _halted(view)) is not None:
        return halted[1]
    state = view.state
    assert state is not None, "a view with no session open is halted"
    step = state.step
    if step is Step.PLAN or view.preparing:
        return "**Preparing the next handover** (the learner chooses it) — please wait."
    if step is Step.READY:
        blocker = start_blocker(view)
        return f"**Ready, but** {blocker}." if blocker else "**Ready** — press **Start trial**."
    if step is Step.RUNNING:
        if (gate := current().gate(view.waiting_for)) is not None:
            return gate.asks
        stage = view.stage
        return f"**Handover running** — {stage_words(stage).dashboard if stage else 'starting'}."
    if step is Step.PLACE:
        slot = state.slot
        assert slot is not None, "a placement is due for the slot at the cursor"
        return (f"**Waiting for the participant** to place handover {slot.position} on "
                "the tablet.")
    if step is Step.HINT:
        slot = state.slot
        assert slot is not None, "a hint is due for the slot at the cursor"
        return (f"**Waiting for the participant's hint** about handover {slot.position} on the "
                "tablet (sooner, later, more, less, or nothing to change).")
    if step is Step.RATE:
        return "**Waiting for the participant** to rate the pair on the tablet."
    if step is Step.ANSWER:
        return (f"**Waiting for the participant's questionnaire** ({len(state.answers)} of "
                f"{len(questions())} answered).")
    return "**Session complete** — press **End session**, then open the next participant."


def _batches(state: SessionState, phase: Phase) -> int:
    return max((s.batch for s in state.slots if s.phase is phase), default=0)


def progress_markdown(view: RunnerView) -> str:
    """Where the protocol stands, 1-based: "Learning batch 2 of 4 · handover 3 of 5"."""
    state = view.state
    if state is None:
        return ""
    assert view.scenario is not None, "an open session's view has its scenario"
    lines = [f"**{view.code}** · {view.scenario.value} · {state.completed} of "
             f"{view.interactions} handovers completed"]
    slot = state.slot
    if state.step is Step.ANSWER:
        lines.append(f"Questionnaire · {len(state.answers)} of {len(questions())} answered")
    elif slot is not None:
        where = PHASE_WORDS[slot.phase]
        if slot.phase in (Phase.LEARNING, Phase.VALIDATION):
            where += f" {slot.batch} of {_batches(state, slot.phase)}"
        if slot.batch_size > 1:
            where += f" · handover {slot.position} of {slot.batch_size}"
        attempt = state.attempts.get(slot.interaction, 0) + (state.step in (Step.PLAN, Step.READY))
        if attempt > 1:
            where += f" · attempt {attempt}"
        lines.append(where)
    if (stopped := stop_headline(state)) is not None:
        lines.append(stopped)
    if state.step is Step.RUNNING:
        lines.append(cycle_markdown(view))
    return "  \n".join(lines)


def cycle_markdown(view: RunnerView) -> str:
    """The running trial's stage within the cycle, the current one in bold."""
    stage, stages, replaced = view.stage, cycle_line(), instead_of()
    shown = [f"**[{stage_name(s)}]**" if s == stage else stage_name(s) for s in stages]
    if stage in replaced:
        shown[stages.index(replaced[stage])] = f"**[{stage_name(stage)}]**"
    line = "cycle: " + " → ".join(shown)
    if view.ready_wait and before_ready(stage):
        line += f"  \nnot ready: {view.ready_wait}"
    return line


def tablet_markdown(view: RunnerView) -> str:
    """The tablet port: how many pages, paired or not, and the pairing code."""
    tablet = view.tablet
    if tablet is None:
        return ""
    pages = f"{tablet.pages} page{'s' if tablet.pages != 1 else ''} open"
    if tablet.ready:
        return f"Tablet: **connected and paired** ({tablet.address}) · pairing code {tablet.code}"
    return f"Tablet: ⚠ **{tablet.blocker()}** ({pages}) · pairing code **{tablet.code}**"


def safety_markdown(view: RunnerView) -> str:
    """The arm's stop state, updated the moment the stop completes, and every trial of the session
    over the lab's safety limits (the moment it is stored)."""
    flags = "".join(f"  \n⚠ **over the lab's safety limit**: {flag}" for flag in view.safety_flags)
    if view.stop == "stopping":
        return f"### Arm: stopping …{flags}"
    if view.stop == "stopped":
        return f"### Arm: STOPPED\nCheck the scene is safe, then **Re-arm**.{flags}"
    fault = f" — ⚠ {view.arm_fault}" if view.arm_fault else ""
    return f"**Arm: armed**{fault}{flags}"


def devices_markdown(view: RunnerView) -> str:
    def line(name: str, text: str, fault: str | None) -> str:
        return f"- **{name}**: {text}" + (f" — ⚠ **{fault}**" if fault else "")
    rig = ["- rehearsal: stand-in UR controller and simulated hand (no hardware)"] if view.rehearsal \
        else []
    arm = {"armed": view.arm, "stopping": f"stopping … ({view.arm})",
           "stopped": f"stopped, waiting for Re-arm ({view.arm})"}[view.stop]
    timing = [line("timing", view.timing, view.timing_warning)] if view.timing else []
    return "\n".join([*rig, line("arm", arm, view.arm_fault), line("hand", view.hand, view.hand_link),
                      line("gripper", view.gripper, None), *timing, *recording_lines(view),
                      line("learner", view.learner, view.learner_fault),
                      *([f"- **learning**: {view.learning}"] if view.learning else []),
                      "", "Recent events:", *[f"- {m}" for m in view.messages]])


def recording_lines(view: RunnerView) -> list[str]:
    """The session's recording: its file, size and streams, a stream named but not found, and a
    file that stopped growing (nothing without a recording)."""
    recording = view.recording
    if recording is None:
        return []
    state = "stopped" if recording.stopped else "recording"
    lines = [f"- **recording** ({recording.kind}, run {recording.run}): {state} "
             f"`{Path(recording.path).name}`, {recording.size / 1000:,.1f} kB"
             + (f" — ⚠ **{recording.warning}**" if recording.warning else ""),
             f"  - streams: {', '.join(recording.streams)}"]
    if recording.missing:
        lines.append(f"  - ⚠ **not found, not recorded**: {', '.join(recording.missing)} "
                     "(named in [recording] streams: start them and open the participant again)")
    return lines


def _local_time(at: str | None) -> str:
    if at is None:
        return "—"
    return datetime.fromisoformat(at).astimezone().strftime("%Y-%m-%d %H:%M")


def overview_status(row: ParticipantSummary) -> str:
    """A participant's status in a word or two (the table's column stays narrow): a session the
    experimenter ended before it was complete is "ended early", one paused otherwise "paused"."""
    if row.status is SessionStatus.PAUSED:
        return "ended early" if row.detail == END_REASON else "paused"
    if row.status is SessionStatus.OPEN and row.detail:
        return "open, paused"
    return row.status.value


def overview_markdown(rows: list[ParticipantSummary]) -> str:
    """Every participant: scenario, progress, status, last activity; why a participant's database
    could not be read is said under the table."""
    if not rows:
        return "No participants yet."
    table = ["| code | scenario | handovers | status | last activity |", "|---|---|---|---|---|"]
    table += [f"| {r.code} | {r.scenario.value if r.scenario else '—'} | {r.completed} of "
              f"{r.interactions} | {overview_status(r)} | {_local_time(r.last_activity)} |"
              for r in rows]
    unreadable = [f"- {r.code}: {r.detail}" for r in rows if r.status is SessionStatus.UNREADABLE]
    return "\n".join(table + (["", "Unreadable:", *unreadable] if unreadable else []))


def plan_markdown(plan: PlanStatus) -> str:
    """The study plan above the new participant's form: the design, the groups so far, what it
    proposes next, and the deviations on record."""
    lines = [f"**Study plan** ({plan.plan.words()}): so far {plan.counts_words()}.",
             f"**{plan.next_words()[0].upper()}{plan.next_words()[1:]}**."]
    if plan.deviations:
        lines.append("⚠ Deviations: " + "; ".join(plan.deviations) + ".")
    return "  \n".join(lines)


def learner_markdown(view: RunnerView, blind: bool, rows: int = 10) -> str:
    """θ* after each learner update and the θ of the latest attempts (validation trials' θ and
    origin hidden when ``blind``)."""
    star = view.theta_star[-1] if view.theta_star else None
    head = (f"θ* (best so far): **a {star.a:.2f}, δ {star.delta:.2f}, k {star.k:.2f}** after "
            f"handover {star.after_interaction}" if star else "θ*: none yet")
    table = ["| trial | handover | phase | a | δ | k | origin | outcome |",
             "|---|---|---|---|---|---|---|---|"]
    for t in view.trials[-rows:]:
        hidden = blind and t.phase is Phase.VALIDATION
        theta = ("hidden", "hidden", "hidden") if hidden else \
            (f"{t.theta_a:.2f}", f"{t.theta_delta:.2f}", f"{t.theta_k:.2f}")
        table.append(f"| {t.trial_index} | {t.interaction} | {t.phase.value} | {' | '.join(theta)} "
                     f"| {'hidden' if hidden else t.origin.value} | "
                     f"{t.outcome.value if t.outcome else 'running'} |")
    history = ", ".join(f"({s.a:.1f}, {s.delta:.2f}, {s.k:.1f})" for s in view.theta_star[-6:])
    blinding = ("_Double-blind: θ and origin of validation trials are hidden._" if blind else
                "_Not blind (serve --unblind): θ and origin of validation trials are shown._")
    return "\n".join([head, "", f"θ* history (latest 6): {history or '—'}", "", *table, "",
                      blinding])
