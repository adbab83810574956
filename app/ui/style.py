"""Looks of the two screens: the tablet's large touch-friendly type, and the "Go!" cue.

viser serves no static files and runs no ``<script>`` from ``add_html``, but a ``<style>`` element
in an ``add_html`` block applies to the whole page, and an ``<audio autoplay>`` element with a
``data:`` URL plays when the browser allows autoplay (see docs/running-a-study.md, "Sound").
"""

from __future__ import annotations

import base64
import io
import wave
from functools import cache

import numpy as np

from app.ui.scale_view import MARKER_PX

ORANGE, BLUE, GREY = "#f08c00", "#1c7ed6", "#495057"

#: The tablet: no 3-D canvas, big text, big buttons, the slider as a big orange drag handle.
TABLET_CSS = f"""
canvas, .mantine-Notification-root {{ display: none !important; }}
.hl-title {{ font-size: 52px; font-weight: 700; text-align: center; padding: 24px 8px 8px; }}
.hl-title.hl-go {{ color: #2b8a3e; font-size: 140px; padding-top: 96px; }}
.hl-title.hl-question {{ font-size: 34px; font-weight: 600; padding: 24px 8px 8px; }}
.hl-detail {{ font-size: 26px; text-align: center; color: #495057; padding: 0 8px 12px; }}
.hl-scale {{ margin: 8px 40px 0; }}
.hl-lane {{ position: relative; }}
.hl-marker {{ position: absolute; transform: translateX(-50%); width: {MARKER_PX}px;
  height: {MARKER_PX}px; border-radius: 50%; background: {BLUE}; color: white;
  font: 700 34px/{MARKER_PX}px sans-serif; text-align: center; }}
.hl-marker.hl-new {{ background: {ORANGE}; box-shadow: 0 0 0 4px white, 0 0 0 7px {ORANGE}; }}
.hl-arrow {{ position: relative; height: 14px; background: {GREY}; margin-top: 10px;
  border-radius: 7px 0 0 7px; }}
.hl-arrow::after {{ content: ""; position: absolute; right: -26px; top: -15px;
  border-left: 30px solid {GREY}; border-top: 22px solid transparent;
  border-bottom: 22px solid transparent; }}
.hl-ends {{ display: flex; justify-content: space-between; font-size: 26px; font-weight: 600;
  padding-top: 8px; }}
.hl-caption {{ text-align: center; font-size: 30px; font-weight: 700; color: {ORANGE};
  min-height: 40px; }}
.mantine-Flex-root:has(> div > .mantine-Flex-root > .mantine-Slider-root) > :first-child {{
  display: none; }}
.mantine-Slider-root {{ margin: 28px 31px 0; height: 88px; }}
.mantine-Slider-track::before {{ background: #dee2e6 !important; }}
.mantine-Slider-bar {{ background: transparent !important; }}
.mantine-Slider-thumb {{ width: 80px !important; height: 80px !important; border-radius: 50% !important;
  background: {ORANGE} !important; border: 5px solid white !important;
  box-shadow: 0 2px 8px rgba(0,0,0,.35); }}
.mantine-Slider-thumb::after {{ content: "\\2194"; color: white; font: 700 40px/70px sans-serif;
  position: absolute; inset: 0; text-align: center; }}
.mantine-Slider-markWrapper {{ display: none; }}
.mantine-NumberInput-root, .mantine-Slider-root + div {{ display: none !important; }}
.mantine-Button-root {{ height: 84px !important; font-size: 32px !important; margin: 8px 0; }}
"""

#: The dashboard: viser's default look, a more visible Stop.
DASHBOARD_CSS = """
.hl-stop .mantine-Button-root { height: 56px !important; font-size: 22px !important; }
"""


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
