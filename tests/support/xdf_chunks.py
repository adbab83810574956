"""Where an XDF file's chunks begin, as pyxdf's own chunk reader walks them: tests that cut a
recording short at a chunk take the chunks' places from pyxdf, not from the product's reading."""

from __future__ import annotations

import io

from pyxdf.pyxdf import _read_chunks

#: XDF's chunk tags (its specification): a stream's header, samples, a clock offset, a footer.
HEADER, SAMPLES, OFFSET, FOOTER = 2, 3, 4, 6
#: A chunk's head: the length's size (1 byte) and length (up to 8), tag (2), stream id (4).
HEAD = 1 + 8 + 2 + 4


def chunks(data: bytes) -> list[tuple[int, int, int | None]]:
    """(start, tag, stream id) of every chunk of the XDF file ``data``."""
    f = io.BytesIO(data)
    f.read(4)  # "XDF:"
    reader, found = _read_chunks(f), []
    while True:
        start = f.tell()
        chunk = next(reader, None)
        if chunk is None:
            return found
        found.append((start, chunk["tag"], chunk.get("stream_id")))
