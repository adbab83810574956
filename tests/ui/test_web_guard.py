"""`handover serve` closed to the outside, tried as a hostile page or a careless set-up would: a real
websocket client (the ``websockets`` package viser itself uses) speaking viser's protocol to the real
server, a real browser for the token, a port already taken by another program."""

from __future__ import annotations

import socket
import subprocess
import sys

import msgspec
import pytest
import viser
from support.browser import (
    TOKEN,
    chromium,
    click,
    fill,
    open_page,
    serve,
    wait_text,
    wait_unlocked,
)
from support.waiting import CEILING_S, tail, wait_for
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from app.ui.guard import open_server

SUBPROTOCOL = f"viser-v{viser.__version__}"
#: The websocket's waits (open, first message, the close): ceilings for a hung server, not bounds.
WS_S = CEILING_S


def _ws(url: str, origin: str | None):
    return connect(url.replace("http://", "ws://"), origin=origin, subprotocols=[SUBPROTOCOL],
                   open_timeout=WS_S)


def _wait_for(served, text: str) -> str:
    """Wait until the server's output says ``text``; return the output."""
    return wait_for(lambda: text in (log := served.log.read_text()) and log,
                    f"{text!r} in the server's output", seen=lambda: tail(served.log.read_text()))


def test_a_share_link_request_is_refused_on_both_ports(tmp_path):
    """viser lets any page ask for a public tunnel (share.viser.studio); neither screen opens one."""
    with serve(tmp_path) as served:
        for url in (served.tablet_url, served.dashboard_url):
            with _ws(url, origin=url) as ws:
                ws.recv(timeout=WS_S)  # connected: the server is sending its state
                ws.send(msgspec.msgpack.encode({"type": "ShareUrlRequest"}))
                _wait_for(served, "share-link request (ShareUrlRequest) from client 0 at "
                                  "127.0.0.1: public tunnels are disabled")
        output = served.shutdown()
    assert output.count("refused share-link request") == 2
    assert "Share URL requested" not in output and "Traceback" not in output


def test_a_websocket_from_a_foreign_origin_is_closed_before_any_message(tmp_path):
    with serve(tmp_path) as served:
        for url in (served.tablet_url, served.dashboard_url):
            with _ws(url, origin=url) as ws:  # positive control: the page the server served
                assert ws.recv(timeout=WS_S)
            for origin in ("http://evil.example", url.replace("127.0.0.1", "attacker.example"),
                           None):
                with _ws(url, origin=origin) as ws, pytest.raises(ConnectionClosed) as closed:
                    ws.recv(timeout=WS_S)
                assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008, origin
        output = served.shutdown()
    assert output.count("refused websocket from 127.0.0.1 with Origin") == 6


@pytest.mark.browser
def test_dashboard_token_guesses_are_slowed_down_and_logged_and_the_right_token_gets_in(tmp_path):
    """Five wrong tokens locked the right one out of that address for a minute (issue 45, item 8):
    now each further try waits before it is checked, the right one included, and gets in."""
    with serve(tmp_path) as served, chromium() as browser:
        page = open_page(browser, served.dashboard_url)
        for attempt in range(5):
            fill(page, "Token", f"guess-{attempt}")
            click(page, "Unlock")
            wait_text(page, "Wrong token.")
            _wait_for(served, f"wrong token from 127.0.0.1 ({attempt + 1} in 60 s; 5 free)")
        fill(page, "Token", "guess-5")  # past the free tries: it waits, then is wrong
        click(page, "Unlock")
        wait_text(page, "Checking the token in 1 s: 5 wrong tokens came from this address")
        _wait_for(served, "wrong token from 127.0.0.1 (6 in 60 s; 5 free)")
        wait_text(page, "Wrong token.")
        fill(page, "Token", TOKEN)  # the right token: it waits too, and gets in
        click(page, "Unlock")
        wait_text(page, "Checking the token in 2 s: 6 wrong tokens came from this address")
        wait_unlocked(page)
        output = served.shutdown()
    assert output.count("dashboard: wrong token from 127.0.0.1") == 6
    assert output.count("dashboard: a token from 127.0.0.1 waits") == 2


def test_a_busy_tablet_port_is_an_error_naming_it(tmp_path):
    """Today's viser would move to the next port — possibly the dashboard's — without a word."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        run = subprocess.run(
            [sys.executable, "-m", "app.cli", "serve", "--study", str(tmp_path / "study"),
             "--tablet-port", str(port), "--dashboard-port", "0"],
            capture_output=True, text=True, timeout=60)  # a ceiling for a hung serve, not a bound
    assert run.returncode != 0 and "dashboard token" not in run.stdout
    assert f"tablet port {port} on 127.0.0.1 is in use" in run.stderr
    assert "Traceback" not in run.stderr


@pytest.mark.parametrize("message", [msgspec.msgpack.encode({"type": "NoSuchMessage"}),
                                     b"\xc1 not msgpack", "text, not bytes"])
def test_a_message_viser_cannot_read_is_one_line_in_the_log_and_other_pages_go_on(tmp_path, message):
    """An unknown message type once printed a KeyError traceback in the experimenter's terminal."""
    with serve(tmp_path) as served:
        with _ws(served.tablet_url, origin=served.tablet_url) as ws:
            ws.recv(timeout=WS_S)
            ws.send(message)
            with pytest.raises(ConnectionClosed):
                while True:
                    ws.recv(timeout=WS_S)
        _wait_for(served, "a page sent a message this server cannot read")
        with _ws(served.tablet_url, origin=served.tablet_url) as ws:  # the server goes on
            assert ws.recv(timeout=WS_S)
        output = served.shutdown()
    assert "Traceback" not in output and output.count("cannot read") == 1, tail(output)


#: GUI updates no viser page sends for a slider (the client sends {"value": <number>} only): a
#: word, nothing, NaN, outside the slider's range, a list, a property other than the value.
FORGED_UPDATES = [{"value": "abc"}, {"value": None}, {"value": float("nan")}, {"value": 7.0},
                  {"value": [1, 2]}, {"disabled": False}, {"value": 0.3, "min": 0.5}]


#: The camera message a viser page sends first (viser's client is connected from then on).
CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 1.0],
          "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800,
          "look_at": [0.0, 0.0, 0.0], "up_direction": [0.0, 0.0, 1.0]}


def test_a_gui_update_no_page_sends_is_refused_in_one_line_and_the_page_goes_on(caplog):
    """A non-numeric slider value from the paired tablet printed an asyncio traceback from viser's
    _handle_gui_updates (issue 45, item 10); a value outside the slider's range was taken as it
    came. Each is refused and logged in one line, the slider keeps its value, and the page's next
    real move counts."""
    server, guard = open_server("127.0.0.1", 0, "tablet")
    sliders: dict[int, viser.GuiSliderHandle] = {}
    moves: list[float] = []

    def connect(client: viser.ClientHandle) -> None:
        slider = client.gui.add_slider("Scale", min=0.0, max=1.0, step=0.001, initial_value=0.5)
        slider.on_update(lambda _: moves.append(slider.value))
        sliders[client.client_id] = slider

    server.on_client_connect(connect)
    url = f"http://127.0.0.1:{server.get_port()}"
    try:
        with _ws(url, origin=url) as ws:
            ws.recv(timeout=WS_S)
            ws.send(msgspec.msgpack.encode(CAMERA))  # viser counts a page as connected from then on
            [slider] = wait_for(lambda: list(sliders.values()), "the page's slider")
            for updates in [*FORGED_UPDATES, {"value": 0.25}]:
                ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage",
                                                "uuid": slider._impl.uuid, "updates": updates}))
            wait_for(lambda: moves, "the real move to 0.25", seen=lambda: guard.refused)
    finally:
        server.stop()
    assert moves == [0.25] and slider.value == 0.25
    assert len(guard.refused) == len(FORGED_UPDATES), guard.refused
    assert all(refusal.startswith("GUI update of 'Scale' ") and refusal.endswith(" at 127.0.0.1)")
               for refusal in guard.refused), guard.refused
    assert "Traceback" not in caplog.text and "exception was never retrieved" not in caplog.text
