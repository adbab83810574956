"""Looks of the two screens: the tablet's large touch-friendly type, and the "Go!" cue.

viser runs no ``<script>`` from ``add_html`` (the page's own script is in the page it serves,
:mod:`app.ui.client_page`), but a ``<style>`` element in an ``add_html`` block applies to the whole
page, and an ``<audio autoplay>`` element with a ``data:`` URL plays when the browser allows
autoplay (see docs/running-a-study.md, "Sound").
"""

from __future__ import annotations

import base64
import io
import wave
from functools import cache

import numpy as np

ORANGE, BLUE, GREY, RED = "#f08c00", "#1c7ed6", "#495057", "#c92a2a"
#: The dashboard's stop button: the page's script never holds a click on it (app/ui/client_page.py).
STOP_LABEL = "STOP ARM"

#: The kiosk: none of viser's own chrome is visible or reachable on the tablet — no settings gear
#: (with its editable server URL and dev settings), no « collapse arrow or panel handles, no
#: connection badge, no notifications, no 3-D canvas — and the panel fills the screen whatever the
#: window's size or orientation. viser 1.1.1 has no switch for these (upstream issue #392); the
#: selectors are its client's stable ``data-dock-*`` attributes and the inline styles of its mobile
#: bottom sheet (``ControlPanel/BottomPanel.tsx``, used below 576 px).
KIOSK_CSS = """
html, body { overscroll-behavior: none; -webkit-user-select: none; user-select: none;
  -webkit-touch-callout: none; }
canvas, .mantine-Notifications-root, [data-dock-region-handle], [data-dock-header],
[data-dock-region-resize], [data-dock-region-collapse] { display: none !important; }
[data-dock-root] > :not([data-dock-region]) { display: none !important; }
[data-dock-region] { left: 0 !important; right: 0 !important; width: 100% !important; }
[data-dock-region] [style*="flex-direction: row"] { width: 100% !important; }
.mantine-Paper-root[style*="position: fixed"] { inset: 0 !important; width: 100% !important;
  max-height: none !important; height: 100% !important; box-shadow: none !important; }
.mantine-Paper-root[style*="position: fixed"] [style*="width: 20em"] { width: 100% !important; }
.mantine-Paper-root[style*="position: fixed"] [style*="height: 3.5em"],
.mantine-Paper-root[style*="position: fixed"] .mantine-Divider-root { display: none !important; }
"""

#: The screen's ``.hl-live`` marker inside viser's ``DisconnectedGate`` (inline ``opacity: 0.5;
#: pointer-events: none`` while the connection is down): present only on a disconnected page.
DISCONNECTED = '[style*="opacity: 0.5"][style*="pointer-events: none"] .hl-live'


#: How long a page without the server's screen stays blank before its cover says why [s]: a page
#: loading normally draws its first screen well within it, so a participant never reads the cover
#: on an ordinary load.
COVER_DELAY_S = 3


def offline_cover(message: str, colour: str, font: str) -> str:
    """CSS that covers the whole page with ``message`` while it has no connection to the server.

    When the connection drops, viser keeps the last screen but dims it and blocks its input (its
    ``DisconnectedGate``: inline ``opacity: 0.5; pointer-events: none``). Over that, the cover
    says what to do; it goes away when the page reconnects and the server draws the current
    screen again. ``.hl-live`` is an empty marker in every screen. A page that shows no screen of
    the server's at all (loading, or a reload while the server is down: viser's own "connecting"
    screens) is blank white at once and shows the message after :data:`COVER_DELAY_S`. The page
    carries this CSS from its first byte (:mod:`app.ui.client_page`) and every screen again."""
    text = message.replace("\n", "\\A ")
    return f"""
body:has({DISCONNECTED})::after, body:not(:has(.hl-live))::after {{
  content: "{text}";
  white-space: pre-wrap; position: fixed; inset: 0; z-index: 2147483647; display: flex;
  align-items: center; justify-content: center; text-align: center; padding: 24px;
  background: white; color: {colour}; font: {font}; }}
body:not(:has(.hl-live))::after {{ animation: hl-cover-late {COVER_DELAY_S}s; }}
body:not(:has(.hl-live))::before {{ content: ""; position: fixed; inset: 0;
  z-index: 2147483646; background: white; }}
@keyframes hl-cover-late {{ from, to {{ opacity: 0; }} }}
"""


#: The tablet's cover: the participant asks the experimenter.
OFFLINE_CSS = offline_cover("Please tell the experimenter.\n\nThe tablet has lost its connection.",
                            RED, "700 var(--hl-title, 44px) / 1.25 sans-serif")

#: The tablet's own look: big type, big buttons, the slider as a big orange drag handle, the scale
#: at a fixed height (stacked "equal" markers close up rather than push Confirm down), sizes for a
#: tablet in either orientation and smaller ones for a phone. The slider's track spans exactly the
#: arrow's length (viser's and Mantine's side paddings removed), so the handle stands under the
#: newest marker from end to end; the lane ends clear of the arrowhead.
TABLET_CSS = f"""
:root {{ --hl-title: 52px; --hl-text: 26px; --hl-marker: 64px; --hl-stack: 70px;
  --hl-lane: clamp(150px, 36vh, 380px); --hl-thumb: 80px; --hl-button: 76px;
  --hl-button-text: 30px; }}
@media (max-height: 900px) and (orientation: landscape) {{
  :root {{ --hl-title: 44px; --hl-text: 24px; --hl-marker: 58px; --hl-thumb: 72px;
    --hl-button: 66px; }} }}
@media (max-width: 600px) {{
  :root {{ --hl-title: 32px; --hl-text: 18px; --hl-marker: 42px; --hl-stack: 46px;
    --hl-thumb: 56px; --hl-button: 58px; --hl-button-text: 22px; }} }}
.hl-title {{ font-size: var(--hl-title); font-weight: 700; text-align: center;
  padding: 16px 8px 4px; line-height: 1.2; }}
.hl-title.hl-go {{ color: #2b8a3e; font-size: calc(2.6 * var(--hl-title)); padding-top: 12vh; }}
.hl-title.hl-question {{ font-size: calc(0.68 * var(--hl-title)); font-weight: 600; }}
.hl-title.hl-unused {{ color: {GREY}; padding-top: 12vh; }}
.hl-detail {{ font-size: var(--hl-text); text-align: center; color: {GREY}; padding: 0 8px 8px;
  line-height: 1.35; }}
.hl-count {{ font-size: var(--hl-text); text-align: center; color: {GREY}; padding-top: 8px; }}
.hl-scale {{ margin: 0 calc(var(--hl-marker) / 2 + 8px); }}
.hl-lane {{ position: relative; height: var(--hl-lane); }}
.hl-marker {{ position: absolute; transform: translateX(-50%); width: var(--hl-marker);
  height: var(--hl-marker); border-radius: 50%; background: {BLUE}; color: white;
  font: 700 calc(0.53 * var(--hl-marker)) / var(--hl-marker) sans-serif; text-align: center;
  box-shadow: 0 0 0 2px white;
  bottom: calc(var(--hl-level) * min(var(--hl-stack),
    (var(--hl-lane) - var(--hl-marker)) / var(--hl-gaps))); }}
.hl-marker.hl-new {{ background: {ORANGE}; box-shadow: 0 0 0 4px white, 0 0 0 7px {ORANGE}; }}
.hl-arrow {{ position: relative; height: 14px; background: {GREY}; margin-top: 24px;
  border-radius: 7px 0 0 7px; }}
.hl-arrow::after {{ content: ""; position: absolute; right: -26px; top: -15px;
  border-left: 30px solid {GREY}; border-top: 22px solid transparent;
  border-bottom: 22px solid transparent; }}
.hl-ends {{ display: flex; justify-content: space-between; font-size: var(--hl-text);
  font-weight: 600; padding-top: 8px; }}
.hl-caption {{ text-align: center; font-size: calc(1.15 * var(--hl-text)); font-weight: 700;
  color: {ORANGE}; height: calc(1.5 * var(--hl-text)); }}
.hl-hint {{ display: inline-block; font-size: var(--hl-text); font-weight: 400; color: {GREY};
  line-height: 1.3; }}
.mantine-Flex-root:has(> div > .mantine-Flex-root > .mantine-Slider-root) > :first-child {{
  display: none; }}
.mantine-Slider-root {{ margin: calc(var(--hl-thumb) / 3) calc(var(--hl-marker) / 2 + 8px) 0;
  height: calc(var(--hl-thumb) + 8px); padding-inline: 0 !important; }}
[style*="padding-inline"]:has(> .mantine-Flex-root > div > .mantine-Flex-root > .mantine-Slider-root) {{
  padding-inline: 0 !important; }}
.mantine-Slider-track::before {{ background: #dee2e6 !important; }}
.mantine-Slider-bar {{ background: transparent !important; }}
.mantine-Slider-thumb {{ width: var(--hl-thumb) !important; height: var(--hl-thumb) !important;
  border-radius: 50% !important; background: {ORANGE} !important; border: 5px solid white !important;
  box-shadow: 0 2px 8px rgba(0,0,0,.35); }}
.mantine-Slider-thumb::after {{ content: "\\2194"; color: white; position: absolute; inset: 0;
  font: 700 calc(0.5 * var(--hl-thumb)) / calc(var(--hl-thumb) - 10px) sans-serif;
  text-align: center; }}
.mantine-Slider-markWrapper, .mantine-Slider-label {{ display: none !important; }}
.mantine-NumberInput-root, .mantine-Slider-root + div {{ display: none !important; }}
.mantine-Button-root {{ height: var(--hl-button) !important; font-size: var(--hl-button-text) !important;
  margin: 4px 0; }}
.mantine-Button-root[style*="--mantine-color-gray"] {{ background: white !important;
  color: #212529 !important; border: 2px solid #adb5bd !important; }}
.mantine-Button-root[style*="--mantine-color-dark"] {{ background: white !important;
  color: {GREY} !important; border: none !important; width: auto !important;
  height: calc(0.7 * var(--hl-button)) !important; font-size: var(--hl-text) !important; }}
.mantine-Button-root:disabled {{ opacity: 0.45; }}
.mantine-TextInput-input {{ height: var(--hl-button) !important; font-size: var(--hl-button-text)
  !important; letter-spacing: 0.3em; text-align: center; }}
"""

#: The dashboard: viser's default look; STOP ARM (the only red button) large, in the pinned
#: safety panel, which no control of the page can collapse, move, shrink or cover. viser 1.1.1 has
#: no switch for its panel chrome (upstream issue #392), so, by its client's ``data-dock-*``
#: attributes: the » / + collapse arrows, the grab handles and resizers are removed; the panel
#: headers, the Safety tab and the dividers take no pointer (a drag on them would undock a panel,
#: which then floats, or resize a column); the settings gear (its editable server URL would
#: disconnect the page) and the command palette (its overlay covers the page; STOP ARM is its only
#: command, and Esc and the button do the same) are hidden — from the page's first byte and on the
#: locked screen too, so none of it shows before the token. STOP ARM's icon is sized with its
#: label and stands in its box (viser 1.1.1 places a button's icon at ``left: 50%`` of its box
#: without shifting it back, so at this size it overlapped the "S"). Tables (the study overview, the
#: learner's trials) keep each cell on one line, apart from the next, and scroll sideways if wide.
DASHBOARD_CSS = f"""
.mantine-Button-root[style*="mantine-color-red"] {{ height: 84px !important;
  font-size: 26px !important; font-weight: 800 !important; background: {RED} !important; }}
.mantine-Button-root[style*="mantine-color-red"] .mantine-Button-section[data-position="left"],
.mantine-Button-root[style*="mantine-color-red"] .mantine-Button-section[data-position="left"] > *,
.mantine-Button-root[style*="mantine-color-red"] .mantine-Button-section svg {{
  width: 1em !important; height: 1em !important; }}
.mantine-Button-root[style*="mantine-color-red"] .mantine-Button-section[data-position="left"] {{
  margin-inline-end: 0.4em !important; }}
.mantine-Button-root[style*="mantine-color-red"] .mantine-Button-section svg {{ left: 0 !important; }}
[data-dock-column-collapse], [data-dock-region-collapse], [data-dock-column-handle],
[data-dock-griphandle], [data-dock-region-handle], [data-dock-region-resize],
[data-dock-header] .mantine-ActionIcon-root,
.mantine-Spotlight-root {{ display: none !important; }}
[data-dock-header], [data-dock-strip], [data-dock-tab], [data-dock-divider] {{
  pointer-events: none !important; }}
[data-dock-leaf] table {{ display: block; overflow-x: auto; border-collapse: collapse; }}
[data-dock-leaf] th, [data-dock-leaf] td {{ white-space: nowrap; padding: 2px 14px 2px 0;
  text-align: left; }}
"""

#: The dashboard's cover when the server is unreachable: this page cannot stop the arm then. viser
#: (1.1.1) retries a lost connection only while its page has the focus (``WebsocketInterface.tsx``:
#: ``!isConnected && document.hasFocus()``); the page's own watchdog (:mod:`app.ui.client_page`)
#: reloads it once the server answers, focused or not.
DASHBOARD_OFFLINE_CSS = offline_cover(
    "SERVER UNREACHABLE\n\nThis dashboard is not connected: its STOP ARM does nothing.\n"
    "Use the PHYSICAL E-STOP if the arm must stop.\n\nThe page reconnects by itself when the "
    "server is back.", RED, "700 34px / 1.3 sans-serif")


def style_block(css: str) -> str:
    return f"<style>{css}</style>"


@cache
def beep_wav(frequency_hz: float = 880.0, seconds: float = 0.35, rate: int = 16000) -> bytes:
    """A short sine beep with soft edges, as a WAV file."""
    t = np.arange(int(seconds * rate)) / rate
    envelope = np.minimum(1.0, np.minimum(t, seconds - t) / 0.02)
    samples = (0.6 * envelope * np.sin(2 * np.pi * frequency_hz * t) * 32767).astype("<i2")
    buffer = io.BytesIO()
    with wave.open(buffer, "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(rate)
        out.writeframes(samples.tobytes())
    return buffer.getvalue()


def audio_cue() -> str:
    """An ``<audio autoplay>`` element that plays :func:`beep_wav` once."""
    data = base64.b64encode(beep_wav()).decode("ascii")
    return f'<audio class="hl-cue" autoplay src="data:audio/wav;base64,{data}"></audio>'
