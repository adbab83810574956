"""The dashboard's token gate on its own clock: five wrong tokens per address and minute, then the
address waits for the window to slide past its oldest failure; other addresses are not affected."""

from __future__ import annotations

from app.ui.guard import TokenGate, same_origin

ADDRESSES = {1: "10.0.0.7", 2: "10.0.0.8"}


def test_an_address_is_refused_unchecked_after_five_failures_until_the_window_slides():
    now = [0.0]
    gate = TokenGate("secret", ADDRESSES.__getitem__, clock=lambda: now[0])
    for second in range(5):
        now[0] = float(second)
        assert gate.attempt(1, "guess") == "Wrong token."
    now[0] = 30.0
    assert gate.attempt(1, "secret").startswith("Too many wrong attempts")  # right, but unchecked
    assert gate.attempt(2, "secret") is None  # another address is not locked out
    now[0] = 60.0  # the first failure (t = 0) has left the window: one more try
    assert gate.attempt(1, "secret") is None
    assert gate.refused_unchecked == 1


def test_same_origin_accepts_only_the_served_host_and_port():
    assert same_origin("http://127.0.0.1:8080", "127.0.0.1:8080", 8080)
    assert same_origin("http://192.168.1.5:8080", "192.168.1.5:8080", 8080)  # a tablet on the LAN
    assert same_origin("http://localhost:8080", "localhost:8080", 8080)
    assert not same_origin(None, "127.0.0.1:8080", 8080)
    assert not same_origin("http://evil.example", "127.0.0.1:8080", 8080)
    assert not same_origin("http://127.0.0.1:8081", "127.0.0.1:8080", 8080)  # the other screen
    assert not same_origin("http://rebound.example:8080", "rebound.example:8080", 8080)  # DNS rebinding
    assert not same_origin("null", "127.0.0.1:8080", 8080)
