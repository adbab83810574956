"""A small liblsl recorder that writes XDF (https://github.com/sccn/xdf/wiki/Specifications), for
tests that must know what the recording holds before they stop it.

LabRecorder (support/lab_recorder.py) pulls its inlets every 500 ms and does not pull again when
told to stop, so whatever arrived in the last pull interval is not in its file, and nothing it
prints says when a sample was pulled: a test could only stop it after waiting for time. This one
pulls every :data:`PULL_S`, keeps what it pulled (:meth:`XDFRecorder.received`) so that a test
waits for the state it needs, and writes the file a lab's recording has: a file header, one
stream header per stream (the stream's full ``<info>``), sample chunks with every time stamp,
clock offsets and a footer per stream. pyxdf reads it back.
"""

from __future__ import annotations

import struct
import threading
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pylsl

from support.waiting import CEILING_S

#: How often the recorder pulls its inlets [s].
PULL_S = 0.02
FILE_HEADER, STREAM_HEADER, SAMPLES, CLOCK_OFFSET, STREAM_FOOTER = 1, 2, 3, 4, 6
NUMERIC = {pylsl.cf_double64: "<f8", pylsl.cf_float32: "<f4", pylsl.cf_int32: "<i4",
           pylsl.cf_int16: "<i2", pylsl.cf_int8: "<i1", pylsl.cf_int64: "<i8"}


def varlen(value: int) -> bytes:
    """An XDF variable-length integer: its byte count (1, 4 or 8), then the value."""
    if value < 1 << 8:
        return struct.pack("<BB", 1, value)
    if value < 1 << 32:
        return struct.pack("<BI", 4, value)
    return struct.pack("<BQ", 8, value)


def chunk(tag: int, content: bytes, stream_id: int | None = None) -> bytes:
    """One chunk: [length of what follows][tag][stream id][content]."""
    body = struct.pack("<H", tag) + (b"" if stream_id is None else struct.pack("<I", stream_id)) + content
    return varlen(len(body)) + body


def sample_chunk(stream_id: int, fmt: int, values: list, stamps: list[float]) -> bytes:
    """A [Samples] chunk, each sample with its time stamp."""
    parts = [varlen(len(stamps))]
    for sample, stamp in zip(values, stamps, strict=True):
        parts.append(struct.pack("<Bd", 8, stamp))
        if fmt == pylsl.cf_string:
            for text in sample:
                raw = text.encode()
                parts.append(varlen(len(raw)) + raw)
        else:
            parts.append(np.asarray(sample, dtype=NUMERIC[fmt]).tobytes())
    return chunk(SAMPLES, b"".join(parts), stream_id)


class Stream:
    """One recorded stream: its inlet and what was pulled from it."""

    def __init__(self, stream_id: int, info: pylsl.StreamInfo) -> None:
        self.id = stream_id
        self.inlet = pylsl.StreamInlet(info, max_buflen=360, recover=False)
        self.info = self.inlet.info(CEILING_S)  # the full description, desc included
        self.format = self.info.channel_format()
        self.inlet.open_stream(CEILING_S)
        self.values: list = []
        self.stamps: list[float] = []


class XDFRecorder:
    """Records the streams named ``names`` (exactly one stream each) into ``path`` until
    :meth:`close`."""

    def __init__(self, path: Path, names: list[str]) -> None:
        self.path = path
        self.streams: dict[str, Stream] = {}
        for number, name in enumerate(names, start=1):
            found = pylsl.resolve_byprop("name", name, 1, CEILING_S)
            assert len(found) == 1, f"{len(found)} LSL streams named {name!r} within {CEILING_S} s"
            self.streams[name] = Stream(number, found[0])
        self._file: BinaryIO = path.open("wb")
        self._file.write(b"XDF:" + chunk(FILE_HEADER, b'<?xml version="1.0"?><info><version>1.0'
                                                      b"</version></info>"))
        for stream in self.streams.values():
            self._file.write(chunk(STREAM_HEADER, stream.info.as_xml().encode(), stream.id))
            self._offset(stream)
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="xdf-recorder", daemon=True)
        self._thread.start()

    def received(self, name: str) -> tuple[list, list[float]]:
        """What was pulled from stream ``name`` so far: (samples, time stamps)."""
        with self._lock:
            stream = self.streams[name]
            return list(stream.values), list(stream.stamps)

    def _offset(self, stream: Stream) -> None:
        """A [ClockOffset] chunk: when, and the outlet's clock minus ours."""
        offset = stream.inlet.time_correction(CEILING_S)
        self._file.write(chunk(CLOCK_OFFSET, struct.pack("<dd", pylsl.local_clock(), offset), stream.id))

    def _run(self) -> None:
        while not self._stopping.wait(PULL_S):
            self._pull()

    def _pull(self) -> None:
        with self._lock:
            for stream in self.streams.values():
                values, stamps = stream.inlet.pull_chunk(timeout=0.0)
                if stamps:
                    self._file.write(sample_chunk(stream.id, stream.format, values, stamps))
                    stream.values.extend(values)
                    stream.stamps.extend(stamps)

    def close(self) -> Path:
        """Pull what is left, write each stream's clock offset and footer, close the file."""
        self._stopping.set()
        self._thread.join()
        self._pull()
        for stream in self.streams.values():
            self._offset(stream)
            first, last = (stream.stamps[0], stream.stamps[-1]) if stream.stamps else (0.0, 0.0)
            footer = (f'<?xml version="1.0"?><info><first_timestamp>{first!r}</first_timestamp>'
                      f"<last_timestamp>{last!r}</last_timestamp><sample_count>{len(stream.stamps)}"
                      f"</sample_count></info>")
            self._file.write(chunk(STREAM_FOOTER, footer.encode(), stream.id))
            stream.inlet.close_stream()
        self._file.close()
        return self.path
