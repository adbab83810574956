"""A message a page sends that viser cannot read (an unknown type, bytes that are not msgpack, text
where viser expects bytes) closes that page's connection, as viser does, but is logged as one line
instead of a traceback in the experimenter's terminal.

viser 1.1.1 decodes each incoming message in ``viser.infra._infra._message_consumer``; what it cannot
decode raises there and ends the connection's handler, which ``websockets`` logs as "connection
handler failed" with the traceback. :class:`UnreadableMessages` is a filter on that logger: the
records whose exception was raised while a message was received or decoded become one warning
line; every other record passes unchanged. Nothing of viser is patched.
"""

from __future__ import annotations

import logging
import traceback

#: The logger ``websockets``' server reports a failed connection handler on.
WEBSOCKETS_LOGGER = "websockets.server"
#: The viser function that receives and decodes a page's messages.
RECEIVER = "_message_consumer"


class UnreadableMessages(logging.Filter):
    """Turns a handler's failure on an unreadable message into one line."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if exc is not None and any(frame.name == RECEIVER
                                   for frame in traceback.extract_tb(exc.__traceback__)):
            record.msg = ("a page sent a message this server cannot read (%s: %s): its "
                          "connection was closed")
            record.args = (type(exc).__name__, exc)
            record.levelno, record.levelname = logging.WARNING, "WARNING"
            record.exc_info, record.exc_text = None, None
        return True


def quiet_unreadable_messages() -> None:
    """Install the filter once for this process."""
    logger = logging.getLogger(WEBSOCKETS_LOGGER)
    if not any(isinstance(f, UnreadableMessages) for f in logger.filters):
        logger.addFilter(UnreadableMessages())
