"""The dashboard's token gate on its own clock: five wrong tokens per address and minute are
answered at once; after that every try from that address waits, longer with each wrong one, and the
right token is still let in — a shared address (a NAT, the lab PC) cannot keep the experimenter out."""

from __future__ import annotations

from collections.abc import Callable

from app.session.access import MAX_WAIT_S
from app.ui.guard import TokenGate, same_origin

ADDRESSES = {1: "10.0.0.7", 2: "10.0.0.8", 3: "10.0.0.7"}


class Later:
    """The gate's timer on the test's clock: what waits, and for how long."""

    def __init__(self, now: list[float]) -> None:
        self.now, self.waiting = now, []

    def __call__(self, delay_s: float, then: Callable[[], None]) -> None:
        self.waiting.append((self.now[0] + delay_s, then))

    def run_until(self, t: float) -> None:
        self.now[0] = t
        due = [w for w in self.waiting if w[0] <= t]
        self.waiting = [w for w in self.waiting if w[0] > t]
        for _, then in sorted(due, key=lambda w: w[0]):
            then()


def test_wrong_tokens_slow_an_address_down_and_the_right_one_is_never_refused():
    """Five wrong tokens from one address locked the right one out for 60 s from it (issue 45,
    item 8): anyone on the lab PC, or behind the same NAT, could keep the experimenter out."""
    now = [0.0]
    later = Later(now)
    gate = TokenGate("secret", ADDRESSES.__getitem__, clock=lambda: now[0], later=later)
    answers: dict[int, list[str | None]] = {1: [], 2: [], 3: []}
    for second in range(5):  # within the free tries: each answered at once
        now[0] = float(second)
        assert gate.attempt(1, "guess", answers[1].append) is None
    assert answers[1] == ["Wrong token."] * 5 and not later.waiting
    now[0] = 10.0
    waiting = gate.attempt(1, "guess", answers[1].append)  # the sixth: it waits
    assert waiting is not None and "5 wrong tokens" in waiting
    [(due, _)] = later.waiting
    assert due == 11.0  # one second for the first try past the free ones
    # the experimenter, on the same address, in another window: waits too (a quick answer would
    # tell the right token from a wrong one), and is let in
    assert gate.attempt(3, "secret", answers[3].append) is not None
    later.run_until(11.0)
    assert answers[1][-1] == "Wrong token." and answers[3] == [None]
    # each wrong one doubles the wait, up to MAX_WAIT_S; the right token still gets in
    waits = []
    for _ in range(6):
        gate.attempt(1, "guess", answers[1].append)
        [(due, _)] = later.waiting
        waits.append(due - now[0])
        later.run_until(due)
    assert waits == [2.0, 4.0, MAX_WAIT_S, MAX_WAIT_S, MAX_WAIT_S, MAX_WAIT_S]
    gate.attempt(3, "secret", answers[3].append)
    later.run_until(now[0] + MAX_WAIT_S)
    assert answers[3] == [None, None]
    assert gate.attempt(2, "secret", answers[2].append) is None and answers[2] == [None]  # others: at once
    now[0] += 61.0  # the window has slid past every wrong one: answered at once again
    assert gate.attempt(1, "secret", answers[1].append) is None and answers[1][-1] is None


def test_a_page_has_one_try_waiting_the_latest_it_gave():
    """A page cannot queue guesses: a try given while its last one waits replaces it, so a page
    guesses at most once per wait, and the token typed last is the one checked."""
    now = [0.0]
    later = Later(now)
    gate = TokenGate("secret", ADDRESSES.__getitem__, clock=lambda: now[0], later=later)
    answers: list[str | None] = []
    for _ in range(5):
        gate.attempt(1, "guess", answers.append)
    for given in ("guess-1", "guess-2", "secret"):
        gate.attempt(1, given, answers.append)
    assert len(later.waiting) == 1
    later.run_until(later.waiting[0][0])
    assert answers == ["Wrong token."] * 5 + [None]


def test_same_origin_accepts_only_the_served_host_and_port():
    assert same_origin("http://127.0.0.1:8080", "127.0.0.1:8080", 8080)
    assert same_origin("http://192.168.1.5:8080", "192.168.1.5:8080", 8080)  # a tablet on the LAN
    assert same_origin("http://localhost:8080", "localhost:8080", 8080)
    assert not same_origin(None, "127.0.0.1:8080", 8080)
    assert not same_origin("http://evil.example", "127.0.0.1:8080", 8080)
    assert not same_origin("http://127.0.0.1:8081", "127.0.0.1:8080", 8080)  # the other screen
    assert not same_origin("http://rebound.example:8080", "rebound.example:8080", 8080)  # DNS rebinding
    assert not same_origin("null", "127.0.0.1:8080", 8080)
