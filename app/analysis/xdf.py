"""Other streams of a lab's XDF recording, aligned to the trials (``handover report --xdf``).

A lab records the study's marker stream (docs/hardware.md, "The study's LSL outlets") together with
streams of its own — an eye tracker's pupil diameter, EEG, skin conductance — into one XDF file
(LabRecorder). pyxdf maps every stream onto the recorder's clock, so the ``go`` markers give each
trial's Go in the same clock as every other sample: each stream is cut into one window around Go
per trial (:data:`WINDOW_S`) and joined with the trial's row of the participant's database (phase,
θ origin, outcome). Which participant: the ``participant`` of the marker stream's description.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, TypeVar

import numpy as np
import pandas as pd

from app.protocol.markers import MARKER_TYPE, ROBOT_TYPE, SOFTWARE, decode
from robot_io.control.stages import Stage

T = TypeVar("T")
#: The window around Go that is kept of every trial [s]: a baseline before, the reach and hold after.
WINDOW_S = (-1.0, 3.0)


class XDFError(ValueError):
    """An XDF file the report cannot align: unreadable, no study markers, a stream not in it."""


@dataclass(frozen=True)
class Channels:
    """One stream of the recording: time stamps (recorder clock) and samples (n × channels)."""

    stamps: np.ndarray
    values: np.ndarray
    labels: list[str]


@dataclass(frozen=True)
class Recording:
    """The study's markers of one participant in an XDF file, and the lab's streams beside them."""

    path: Path
    participant: str
    markers: list[tuple[float, dict]]  # (time stamp, marker), in the recorder's clock
    streams: dict[str, Channels]
    cut_short: list[str]  # the streams that end early, in words (a file cut short)

    def times_of(self, event: str) -> dict[int, float]:
        """Trial index → the time of its ``event`` marker (``go``, ``release``, …)."""
        return {m["trial"]: stamp for stamp, m in self.markers if m["event"] == event}

    def trial_times(self, event: str) -> dict[int, float]:
        """Trial index → its ``event`` marker's ``t`` (seconds after Go)."""
        return {m["trial"]: m["t"] for _, m in self.markers if m["event"] == event}


def _desc(stream: dict, key: str) -> str | None:
    desc = stream["info"].get("desc") or [None]
    if not isinstance(desc[0], dict) or key not in desc[0]:
        return None
    return desc[0][key][0]


def _labels(stream: dict, count: int) -> list[str]:
    desc = stream["info"].get("desc") or [None]
    try:
        labels = [c["label"][0] for c in desc[0]["channels"][0]["channel"]]
    except (KeyError, IndexError, TypeError):
        labels = []
    return labels if len(labels) == count else [f"channel {i}" for i in range(count)]


def _numeric(stream: dict) -> bool:
    return stream["info"]["channel_format"][0] != "string"


def _name(stream: dict) -> str:
    return stream["info"]["name"][0]


def readable(path: Path, read: Callable[[], T]) -> T:
    """``read()``, or an :class:`XDFError` saying that ``path`` is not a readable XDF file (a file
    cut short ends in a chunk's XML or binary header: ParseError, struct.error, KeyError; pyxdf's
    reading of a missing byte is a TypeError)."""
    try:
        return read()
    except (OSError, ValueError, EOFError, RuntimeError, SyntaxError, struct.error, KeyError,
            IndexError, TypeError) as exc:
        raise XDFError(f"{path}: not a readable XDF file ({type(exc).__name__}: {exc}); a file "
                       "cut short (a copy that stopped, a recorder that crashed) loses its end") \
            from exc


#: An XDF chunk's tag for samples, and how many bytes of tag and stream id precede them.
SAMPLES_TAG, TAG_AND_ID = 3, 6


@dataclass(frozen=True)
class WholeChunks:
    """What pyxdf can read of an XDF file that may be cut short: its chunks up to the first one the
    file does not hold whole. XDF lays each chunk out as one byte giving the size of the length (1,
    4 or 8), the length (little endian), then that many bytes of tag and content. pyxdf reads a cut
    samples chunk (tag 3) as far as it goes, but raises on a cut anywhere else (a chunk's length,
    its tag or stream id, a clock offset, a stream header): such a chunk is left out, and said."""

    path: Path
    length: int  # the bytes pyxdf is given
    size: int  # the file's

    @classmethod
    def of(cls, path: Path) -> WholeChunks:
        with Path(path).open("rb") as f:
            size = f.seek(0, io.SEEK_END)
            f.seek(0)
            return cls(Path(path), _readable_length(f, size), size)

    def open(self) -> str | BinaryIO:
        """The input for one pyxdf call (which closes a file it was given): the file's name when
        pyxdf reads it all, else a copy of the bytes it can read."""
        if self.length == self.size:
            return str(self.path)
        with self.path.open("rb") as f:
            return io.BytesIO(f.read(self.length))

    @property
    def left_out(self) -> list[str]:
        """The cut chunk, in words (none when the file is read whole)."""
        if self.length == self.size:
            return []
        return [f"the file ends {self.size - self.length} bytes into a chunk, which is left out "
                "(cut short: a copy that stopped, a recorder that crashed)"]


def _readable_length(f: BinaryIO, size: int) -> int:
    """How many bytes of the XDF file ``f`` (``size`` bytes) pyxdf reads without raising (see
    :class:`WholeChunks`): all of a file that is whole, or not XDF at all (pyxdf says so)."""
    start = 4
    if f.read(start) != b"XDF:":
        return size
    while start < size:
        f.seek(start)
        count = f.read(1)[0]
        if count not in (1, 4, 8):  # not a cut: pyxdf reads on from the next boundary chunk
            return size
        length = f.read(count)
        end = start + 1 + count + int.from_bytes(length, "little")
        if len(length) < count or end > size:  # the last chunk, cut
            whole_header = len(length) == count and size - (start + 1 + count) >= TAG_AND_ID
            tag = int.from_bytes(f.read(2), "little") if whole_header else None
            return size if tag == SAMPLES_TAG else start
        start = end
    return size


def _samples(stream: dict) -> np.ndarray:
    """A numeric stream's samples as (samples × channels), also when it has none."""
    channels = int(stream["info"]["channel_count"][0])
    return np.asarray(stream["time_series"], dtype=float).reshape(len(stream["time_stamps"]), channels)


def _cut_short(stream: dict) -> str | None:
    """Why ``stream`` ends early, if it does: LabRecorder closes each stream with a footer that
    counts its samples; a file cut short has none, and a chunk cut in the middle leaves fewer."""
    footer = (stream.get("footer") or {}).get("info") or {}
    if not footer:
        return (f"stream {_name(stream)!r} ends early: the file has no end of it (cut short, or the "
                "recorder did not stop cleanly); trials after its last sample have no data")
    counted = int(footer.get("sample_count", ["0"])[0])
    if len(stream["time_stamps"]) < counted:
        return (f"stream {_name(stream)!r} ends early: {len(stream['time_stamps'])} of its {counted} "
                "samples could be read (a chunk was cut)")
    return None


def load_recording(path: Path, names: Sequence[str] = ()) -> Recording:
    """The study's markers and the lab's numeric streams in ``path`` (only those named ``names``
    when given; every numeric stream but the study's robot stream otherwise). Only those are read,
    never the robot stream: its samples are the database's. An :class:`XDFError` names what is
    missing or wrong: pyxdf (the ``xdf`` extra), the study's marker stream, a named stream."""
    try:
        import pyxdf
    except ImportError as exc:
        raise XDFError("reading XDF needs pyxdf: pip install 'handover-lab[xdf]'") from exc
    whole = readable(path, lambda: WholeChunks.of(path))
    cut = "".join(f"; {why}" for why in whole.left_out)
    headers = readable(path, lambda: pyxdf.resolve_streams(whole.open()))
    found = sorted(h["name"] for h in headers)
    missing = [name for name in names if name not in found]
    if missing:
        raise XDFError(f"{path}: no stream named {missing}; the file holds {found}")
    robot = [h["name"] for h in headers if h["type"] == ROBOT_TYPE and h["name"] in names]
    if robot:
        raise XDFError(f"{path}: {robot} is the study's robot stream, whose samples the database "
                       "holds (Fig. 4 draws them): name the lab's own streams")
    chosen = [h["stream_id"] for h in headers if h["type"] == MARKER_TYPE or (
        h["name"] in names if names else h["type"] != ROBOT_TYPE and h["channel_format"] != "string")]
    streams = readable(path, lambda: pyxdf.load_xdf(whole.open(), select_streams=chosen)[0]) \
        if chosen else []
    ours = [s for s in streams if _desc(s, "software") == SOFTWARE and s["info"]["type"][0] == MARKER_TYPE]
    if len(ours) != 1:
        raise XDFError(f"{path}: {len(ours)} study marker streams (type Markers from {SOFTWARE}), "
                       f"1 needed; the file holds {found}{cut}")
    markers, lab = ours[0], {}
    for stream in streams:
        name = _name(stream)
        if stream["info"]["type"][0] == MARKER_TYPE and name not in names:
            continue
        if not _numeric(stream):
            raise XDFError(f"{path}: stream {name!r} holds strings; only numeric streams are drawn")
        values = _samples(stream)
        lab[name] = Channels(np.asarray(stream["time_stamps"]), values, _labels(stream, values.shape[1]))
    participant = _desc(markers, "participant")
    if participant is None:
        raise XDFError(f"{path}: the study marker stream's description names no participant")
    decoded, torn = decoded_markers(path, markers)
    if not decoded:
        raise XDFError(f"{path}: the study marker stream holds no markers, so no trial to align{cut}")
    return Recording(path=Path(path), participant=participant, markers=decoded, streams=lab,
                     cut_short=whole.left_out + [why for s in streams if (why := _cut_short(s))]
                     + torn)


def decoded_markers(path: Path, markers: dict) -> tuple[list[tuple[float, dict]], list[str]]:
    """The study's markers, decoded (``app.protocol.markers``), and what was left out: in a marker
    stream cut short (:func:`_cut_short`) the cut can fall inside the last marker's text, which is
    then left out and said; any other marker that does not decode is an :class:`XDFError`."""
    pairs = list(zip(markers["time_stamps"], markers["time_series"], strict=True))
    decoded = []
    for number, (stamp, text) in enumerate(pairs, start=1):
        try:
            decoded.append((float(stamp), decode(text[0])))
        except ValueError as exc:
            if number == len(pairs) and _cut_short(markers):
                return decoded, [f"stream {_name(markers)!r}: its last marker was cut in the middle "
                                 "and is left out"]
            raise XDFError(f"{path}: marker {number} of {len(pairs)} of the study's marker stream "
                           f"is not a study marker ({exc})") from exc
    return decoded, []


def around_go(recording: Recording, trials: pd.DataFrame,
              window: tuple[float, float] = WINDOW_S) -> pd.DataFrame:
    """Every sample of the lab's streams within ``window`` of each trial's Go: one row per sample
    and channel (``participant``, ``trial_index``, ``phase``, ``origin``, ``outcome``, ``stream``,
    ``channel``, ``t`` since Go, ``value``). ``trials``: the study's trials table; a ``go`` marker
    of a trial the database does not have is an :class:`XDFError` (another study's recording)."""
    mine = trials[trials["participant"] == recording.participant].set_index("trial_index")
    go = recording.times_of(Stage.GO)
    unknown = sorted(set(go) - set(mine.index))
    if unknown:
        raise XDFError(f"{recording.path}: trials {unknown} of {recording.participant} are not in the "
                       f"study's database (it has {sorted(mine.index)})")
    frames = []
    for index, at in sorted(go.items()):
        trial = mine.loc[index]
        for name, channels in recording.streams.items():
            keep = (channels.stamps >= at + window[0]) & (channels.stamps <= at + window[1])
            t = channels.stamps[keep] - at
            for column, label in enumerate(channels.labels):
                frames.append(pd.DataFrame({
                    "participant": recording.participant, "trial_index": index,
                    "phase": trial["phase"], "origin": trial["origin"], "outcome": trial["outcome"],
                    "stream": name, "channel": label, "t": t, "value": channels.values[keep, column]}))
    columns = ["participant", "trial_index", "phase", "origin", "outcome", "stream", "channel", "t", "value"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)
