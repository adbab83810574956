"""What ``handover serve`` prints on the experimenter's terminal: the two addresses, the participant
and the token, nothing else before them (before, liblsl's INFO lines from C and viser's two boxed
banners came first); with ``-v`` those are shown too."""

from __future__ import annotations

import re

from support.browser import TOKEN, serve

#: serve's whole start-up output without -v, up to its last line (the token).
QUIET_START = re.compile(
    r"tablet \(participant\):     http://127\.0\.0\.1:\d+\n"
    r"dashboard \(experimenter\): http://127\.0\.0\.1:\d+\n"
    r"participant:              T01 \(perturbed\), 0 of 9 handovers done\n"
    rf"dashboard token:          {TOKEN}\n")


def start_up(log: str) -> str:
    """The output up to and including the token's line."""
    return log[:log.index("\n", log.index("dashboard token:")) + 1]


def test_the_terminal_shows_the_addresses_participant_and_token_and_the_rest_with_v(
        tmp_path, monkeypatch):
    """Slow (~20 s in a loaded full run): two `handover serve` processes, each started up to its
    open participant (rig process, learner) and shut down."""
    # the lab's own liblsl configuration, if the machine has one, would decide liblsl's log
    monkeypatch.delenv("LSLAPICFG", raising=False)
    with serve(tmp_path / "quiet", "--participant", "T01", "--scenario", "perturbed",
               verbose=False) as quiet, \
            serve(tmp_path / "verbose", "--participant", "T01", "--scenario", "perturbed") as loud:
        quiet_log, loud_log = start_up(quiet.log.read_text()), start_up(loud.log.read_text())
        quiet.shutdown()
        loud.shutdown()
    assert QUIET_START.fullmatch(quiet_log), quiet_log
    before = loud_log[:loud_log.index("tablet (participant):")]
    assert "Loaded default config" in before and before.count("── viser ──") == 2, before
