"""The GUI updates a page may send: what viser's own client sends, and nothing else.

viser's client sends ``GuiUpdateMessage`` with ``{"value": v}`` only (``ControlPanel/Generated.tsx``'s
``setValue``, ``components/Button.tsx``), ``v`` of the input's own kind. viser 1.1.1's server
(``GuiApi._handle_gui_updates``) casts whatever comes with the input's type: a word for a slider
raised ValueError in its event loop (an asyncio traceback in the experimenter's terminal, issue 45,
item 10), a number outside the slider's range was taken as it came, and any other property name
failed an assertion. :func:`forged` says what is wrong with an update (None: it is one a page
sends); :func:`checked` wraps viser's handler so that a forged update is refused before viser sees
it, and :mod:`app.ui.guard` installs it on every page's connection.
"""

from __future__ import annotations

import inspect
import math
import reprlib
from collections.abc import Callable, Coroutine
from typing import Any

from viser import _messages
from viser._gui_api import GuiApi
from viser.infra import ClientId
from viser.infra._messages import Message

#: A handler of the messages a page sends, as viser's websocket interfaces keep them.
Handler = Callable[[ClientId, Message], Coroutine[Any, Any, Any] | None]


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _fits(value: Any, current: Any, props: Any) -> str | None:
    """Why ``value`` cannot be the value of an input whose value is ``current`` (None: it can)."""
    if isinstance(current, bool):
        return None if isinstance(value, bool) else "not true or false"
    if isinstance(current, int | float):
        if not _number(value):
            return "not a finite number"
        low, high = getattr(props, "min", None), getattr(props, "max", None)
        if (low is not None and value < low) or (high is not None and value > high):
            return f"outside [{low}, {high}]"
        return None
    if isinstance(current, str):
        if not isinstance(value, str):
            return "not text"
        options = getattr(props, "options", None)
        return None if options is None or value in options else "not one of its options"
    if isinstance(current, tuple):
        if not isinstance(value, list | tuple) or (current and len(value) != len(current)):
            return f"not {len(current)} values"
        return next((why for item in value if (why := _fits(item, current[0], None)) is not None),
                    None) if current else None
    return None  # an input of another kind: viser's own cast decides


def forged(gui: GuiApi, message: _messages.GuiUpdateMessage) -> str | None:
    """What is wrong with ``message`` for its input on ``gui`` (None: a page sends such updates,
    or it names no input of this page, which viser ignores itself)."""
    handle = gui._gui_input_handle_from_uuid.get(message.uuid)
    if handle is None:
        return None
    label = getattr(handle._impl.props, "label", None) or message.uuid
    if set(message.updates) != {"value"}:
        return f"GUI update of {label!r} sets {sorted(message.updates)}: a page sets the value only"
    why = _fits(message.updates["value"], handle._impl.value, handle._impl.props)
    if why is not None:
        return f"GUI update of {label!r} to {reprlib.repr(message.updates['value'])}: {why}"
    return None


def checked(gui: GuiApi, handler: Handler, refuse: Callable[[int, str], None]
            ) -> Callable[[ClientId, _messages.GuiUpdateMessage], Coroutine[Any, Any, None]]:
    """viser's ``handler`` of ``gui``'s updates, behind :func:`forged`: a forged update goes to
    ``refuse`` (its client and why) and no further."""
    async def handle(client_id: ClientId, message: _messages.GuiUpdateMessage) -> None:
        why = forged(gui, message)
        if why is not None:
            refuse(client_id, why)
            return
        handled = handler(client_id, message)
        if inspect.isawaitable(handled):
            await handled

    return handle
