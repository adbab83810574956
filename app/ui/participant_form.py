"""The dashboard's form under **Study** that creates or resumes a participant: the code, the
scenario, the seed and the two confirmations (a seed reused, a rig changed).

No default picks a condition: with a study plan (``[study]`` in lab.toml) the scenario starts at
what the plan proposes for the next participant — said above it, with the groups' counts — and a
choice that differs is named as a deviation before Create (it is recorded with the participant);
without a plan it starts at "— choose —" and a new code is refused until one is chosen. A known
code resumes its session whatever the field says."""

from __future__ import annotations

from collections.abc import Callable

import viser

from app.protocol.seeds import parse_seed
from app.session.runner import RunnerView, SessionRunner
from app.ui.status_text import plan_markdown
from robot_io.hands.simulated_hand import Scenario
from session_store.models import check_participant_code

#: The scenario field's value before the experimenter chose one (no study plan).
CHOOSE = "— choose —"


def build_participant_form(gui: viser.GuiApi, view: RunnerView, runner: SessionRunner,
                           act: Callable[[Callable[[], object]], None]) -> None:
    """The open participant's line, or the form that opens one (``act`` runs its action and
    shows a refusal)."""
    if view.code is not None:
        assert view.scenario is not None, "an open session's view has its scenario"
        gui.add_markdown(f"Open: **{view.code}** ({view.scenario.value}, seed {view.seed}). "
                         "End the session to open or create another participant.")
        return
    plan = view.plan
    proposed = None if plan is None or plan.next is None else plan.next.proposed
    gui.add_markdown("A known code resumes its session; a new code creates one.")
    if plan is not None:
        gui.add_markdown(plan_markdown(plan))
    code = gui.add_text("Code", "")
    code_error = gui.add_markdown("")
    scenario = gui.add_dropdown("Scenario", [CHOOSE, *(s.value for s in Scenario)],
                                initial_value=CHOOSE if proposed is None else proposed.value)
    deviation = gui.add_markdown("")
    seed = gui.add_text("Seed (empty: a fresh random one)", "")
    reuse = gui.add_checkbox("Reuse a seed already used in this study", False)
    rig_change = gui.add_checkbox("Confirm a rig change (resume on other devices)", False)
    open_button = gui.add_button("Create or resume")

    def chosen() -> Scenario | None:
        return None if scenario.value == CHOOSE else Scenario(scenario.value)

    def check_code() -> bool:
        """The code's error under its field while it is wrong (cleared once it is right)."""
        try:
            check_participant_code(code.value.strip())
        except ValueError as exc:
            code_error.content = f"⚠ {exc}" if code.value.strip() else ""
            return False
        code_error.content = ""
        return True

    @code.on_update
    def _(_: viser.GuiEvent) -> None:
        check_code()

    @scenario.on_update
    def _(_: viser.GuiEvent) -> None:
        why = None if plan is None else plan.choice_words(chosen())
        deviation.content = "" if why is None else f"⚠ {why}"

    def open_session() -> None:
        if not check_code():
            code_error.content = code_error.content or "⚠ enter the participant's code"
            return
        act(lambda: runner.open(
            code.value.strip(), chosen(), parse_seed(seed.value) if seed.value.strip() else None,
            confirm_rig_change=rig_change.value, confirm_seed_reuse=reuse.value))

    open_button.on_click(lambda _: open_session())
