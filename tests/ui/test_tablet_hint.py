"""Coactive hints on the tablet (``[protocol] coactive``, issue 40), by touch in headless Chromium
against `handover serve`.

After a handover placed by touch the tablet asks whether the robot should do anything differently;
the participant taps a choice and Confirm. A tap on a choice alone records nothing. The hint is
stored (its row and its ``hint_given`` event, the participant's), exported, and reaches the learner:
its next snapshot holds the hinted point, never run, preferred to the handover, and the learner
plans another θ than it would have without it. The next hint is entered by the experimenter on the
dashboard, for the participant; the third is "it was fine" (no hint). The hint screen names no
parameter and shows no number, and fits a tablet in either orientation without scrolling
(screenshots in /tmp/tablet-shots/).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    button,
    chromium,
    click,
    confirm_placement,
    fill,
    in_viewport,
    open_folder,
    open_participant,
    open_screens,
    run_trial,
    serve,
    settle,
    shot,
    tablet_screen,
    tap,
    touch_drag_to,
    wait_enabled,
    wait_function,
    wait_still,
    wait_text,
)
from support.engine import protocol_toml, study_config

from app.learning.coactive import hint_id
from app.learning.config import LearnerSnapshot
from app.learning.learner import PreferenceLearner
from app.ui.tablet import HINTS
from session_store.export import export_study, load_study, read_table
from session_store.store import ParticipantStore
from session_store.vocabulary import Hint, Rater

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Two initial handovers, one learning batch of two, the best; hints after each placement.
PROTOCOL = protocol_toml({"initial_trials": 2, "batch_size": 2, "learning_batches": 1,
                          "best_trials": 1, "validation_batches": 0, "coactive": True})
#: The tablet in landscape and in portrait (an 11-inch iPad's CSS pixels).
SIZES = {"landscape": (1180, 820), "portrait": (820, 1180)}
SHOTS = Path("/tmp/tablet-shots")
#: What would tell the participant about θ: a parameter's name or symbol.
PARAMETER_WORDS = re.compile(r"[δθ]|\b(delta|theta|k|gain|coupling|parameters?)\b|\ba\s*[=:]",
                             re.IGNORECASE)
#: The participant's seed: its learner's first query with the participant's "sooner" about handover
#: 1 stands at another θ than without it (the query of so few data stands at a corner of the box,
#: and for some seeds at the same corner either way: 3 of seeds 1–6 differ).
SEED = "4"
#: The experimenter's button for "React more to my hand" (app/ui/on_behalf.py).
ON_BEHALF_MORE = "They said: React more to my hand"


#: Whether the choice ``t`` is the one chosen (orange: app/ui/tablet.py Choice) and Confirm enabled.
CHOSEN_JS = """t => { const buttons = [...document.querySelectorAll('button')];
  const named = n => buttons.find(b => b.innerText.trim() === n);
  const chosen = named(t), confirm = named('Confirm');
  return !!chosen && (chosen.getAttribute('style') || '').includes('orange')
    && !!confirm && !confirm.disabled; }"""


def wait_chosen(tablet: Page, text: str) -> None:
    """Wait until the server has taken the tap on the choice ``text``: chosen, Confirm enabled."""
    wait_function(tablet, CHOSEN_JS, f"the choice {text!r} chosen and Confirm enabled", arg=text)


def test_a_hint_given_by_touch_is_stored_exported_and_learned(tmp_path: Path) -> None:
    """Slow: three handovers on the wall clock, each placed by touch and followed by a hint (at two
    tablet sizes the first), until the real learner plans its first query from them."""
    with serve(tmp_path, protocol_toml=PROTOCOL) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        fill(dashboard, "Seed (empty: a fresh random one)", SEED)
        open_participant(dashboard, "P01")
        open_folder(dashboard, "Enter for the participant")

        # Handover 1, placed by touch: the hint screen follows.
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.3)
        confirm_placement(tablet)
        assert tablet_screen(tablet, not_="place") == "hint"
        wait_text(dashboard, "Waiting for the participant's hint")
        shown = tablet.inner_text("body")
        assert not PARAMETER_WORDS.search(shown) and not re.search(r"\d", shown), shown
        for name, (width, height) in SIZES.items():
            tablet.set_viewport_size({"width": width, "height": height})
            wait_still(tablet)
            off = [text for text, _ in [*HINTS, ("Confirm", "")] if not in_viewport(tablet, text)]
            assert not off, f"{name} {width}×{height}: not wholly on the screen: {off}"
            shot(tablet, SHOTS, f"hint-{name}")

        # A stray tap on a choice only chooses it; the participant changes their mind, confirms.
        settle()
        tap(tablet, "Arrive later: wait more for my hand")
        wait_chosen(tablet, "Arrive later: wait more for my hand")  # the server took the tap
        stored = load_study(served.study, ("hints",)).tables["hints"]
        assert stored.empty, f"a tap on a choice alone stored a hint:\n{stored}"
        assert tablet_screen(tablet) == "hint"
        tap(tablet, "Arrive sooner: wait less for my hand")
        wait_chosen(tablet, "Arrive sooner: wait less for my hand")
        shot(tablet, SHOTS, "hint-chosen")
        tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="hint") == "wait"

        # Handover 2: the experimenter enters the participant's hint on the dashboard.
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.7)
        confirm_placement(tablet)
        assert tablet_screen(tablet, not_="place") == "hint"
        wait_text(dashboard, "After handover 2")
        button(dashboard, ON_BEHALF_MORE).scroll_into_view_if_needed()
        shot(dashboard, SHOTS, "dashboard-hint")
        click(dashboard, ON_BEHALF_MORE)
        assert tablet_screen(tablet, not_="hint") == "wait"

        # Handover 3, the learning batch's first (θ* so far): nothing to change.
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.2)
        confirm_placement(tablet)
        assert tablet_screen(tablet, not_="place") == "hint"
        settle()
        tap(tablet, "No, it was fine")
        wait_chosen(tablet, "No, it was fine")
        tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="hint") == "wait"
        wait_enabled(dashboard, "Start trial")  # the learner planned its first query (handover 4)
        served.shutdown()

    store = ParticipantStore.open(served.study, "P01")
    try:
        hints, events = store.rows("hints"), store.events()
        trials = {t.interaction: t for t in store.rows("trials")}
        snapshots = store.rows("learner_snapshots")
    finally:
        store.close()

    # (a) stored: the row and the event, each the participant's, with θ' of the hint
    assert [(h.interaction, h.hint, h.actor) for h in hints] == [
        (1, Hint.SOONER, Rater.PARTICIPANT), (2, Hint.MORE, Rater.EXPERIMENTER),
        (3, None, Rater.PARTICIPANT)]
    assert (hints[2].hinted_a, hints[2].hinted_delta, hints[2].hinted_k) == (None, None, None)
    low, high = study_config().theta_bounds["delta"]
    theta = trials[1].theta
    expected = {"a": theta.a, "delta": max(theta.delta - 0.2 * (high - low), low), "k": theta.k}
    assert expected["delta"] < theta.delta, "θ of handover 1 stood at δ's lower edge"
    assert {"a": hints[0].hinted_a, "delta": hints[0].hinted_delta, "k": hints[0].hinted_k} == \
        pytest.approx(expected)
    given = [e for e in events if e.kind == "hint_given"]
    assert [(e.actor.value, e.payload["interaction"], e.payload["hint"]) for e in given] == [
        ("participant", 1, "sooner"), ("experimenter", 2, "more"), ("participant", 3, None)]
    assert given[0].payload["hinted"] == pytest.approx(expected)
    assert given[2].payload["hinted"] is None

    # (b) exported
    export_study(served.study, tmp_path / "export")
    exported = read_table(tmp_path / "export", "hints").set_index("interaction")
    assert exported["hint"].fillna("").to_dict() == {1: "sooner", 2: "more", 3: ""}
    assert exported["actor"].to_dict() == {1: "participant", 2: "experimenter", 3: "participant"}
    assert exported.loc[1, "hinted_delta"] == pytest.approx(expected["delta"])

    # (c) learned: the snapshot that planned the first query (interaction 4; interaction 3 was θ*)
    # holds θ' ≻ θ, and without the participant's hint the learner would have planned another θ
    snapshot = LearnerSnapshot.model_validate_json(
        next(s for s in snapshots if s.after_interaction == 3).state)
    hinted = hint_id("1")
    unshown = {i.interaction_id: i.theta for i in snapshot.interactions if not i.shown}
    assert unshown[hinted] == pytest.approx(expected)
    assert any((c.winner, c.loser) == (hinted, "1") for c in snapshot.comparisons)
    [planned] = [e.payload for e in events if e.kind == "theta_planned"
                 and e.payload["interaction"] == 4]
    assert planned["origin"] == "learned", planned
    planned_theta = {name: planned[name] for name in ("a", "delta", "k")}
    assert PreferenceLearner.restore(snapshot).suggest().theta == pytest.approx(planned_theta)
    without = snapshot.model_copy(update={
        "interactions": [i for i in snapshot.interactions if i.interaction_id != hinted],
        "comparisons": [c for c in snapshot.comparisons if hinted not in (c.winner, c.loser)]})
    unhinted = PreferenceLearner.restore(without).suggest().theta
    assert unhinted is not None and unhinted != pytest.approx(planned_theta, abs=1e-3), unhinted
