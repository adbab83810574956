"""The session's own XDF recording (``[recording]``, issue 47): started when a participant's
session opens — before its first trial — and stopped when it closes, after its last; a resumed
session records a new run (:mod:`session_store.recordings` names the files).

What it records: the session's own LSL outlets always (found by their ``source_id``, which names
this session), and the lab's streams named in ``[recording] streams`` (by name or type), looked for
once, when the session opens; one named but absent is a warning the dashboard shows before Start.

Who records: LabRecorder's engine in a process of the session (``labrecorder``,
:mod:`app.session.xdf_engine`) or the lab's LabRecorder over its remote control (``labrecorder_rcs``,
:mod:`app.session.rcs_client`). Neither says whether it records, so the session watches the file
itself: it must appear within ``start_timeout_s`` of the start (else the session does not open), and
while a trial streams (its robot samples, ~20 kB/s) it must grow; a file that stops growing for
``stall_s`` is a warning, published the moment it is seen.

Threads: the recording is made and closed on the engine thread (:class:`EngineSide` opens it with the
session and closes it first when the session closes, before the outlets, so the recorder takes the
session's last markers); its watch thread (``recording-watch``) reads the file's size and owns the
status, which other threads read as one immutable :class:`RecordingStatus`.
"""

from __future__ import annotations

import importlib.util
import json
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pylsl
from pydantic import BaseModel, ConfigDict

from app.protocol import events as ev
from app.protocol.state import SessionState
from app.session.config import RecordingSettings
from app.session.rcs_client import RecorderError, RemoteLabRecorder
from robot_io.control.stages import Stage
from session_store.recordings import next_run, recording_path, recordings_root

log = logging.getLogger(__name__)

#: How often the watch thread reads the file's size [s].
WATCH_S = 0.25
#: How long the close waits for the watch thread's end [s] (a look and a published warning).
WATCH_JOIN_S = 2.0
#: How long the session's own outlets are looked for (they were opened just before) [s].
OWN_STREAMS_S = 5.0
#: LabRecorder pulls its streams every 500 ms and not again when stopped: the recording stops no
#: sooner than this after the session's last marker, so that the file holds it [s].
LAST_PULL_S = 1.0
#: How long the engine process may take to close the file after ``stop`` [s]: it joins its
#: clock-offset threads (up to 5 s each) before it writes the footers.
CLOSE_S = 15.0


class RecordingStatus(BaseModel):
    """The recording as the dashboard shows it."""

    model_config = ConfigDict(frozen=True)

    kind: str
    path: str
    run: int
    size: int = 0  # bytes on disk
    streams: list[str] = []  # what is recorded
    missing: list[str] = []  # named in [recording] streams, not found when the session opened
    warning: str | None = None  # the file stopped growing while a trial streamed
    stopped: bool = False


def resolve_streams(settings: RecordingSettings,
                    own: list[str]) -> tuple[list[pylsl.StreamInfo], list[str]]:
    """The session's own streams (by ``source_id``) and the lab's named ones (by name or type);
    the names of [recording] streams that none matched."""
    found = []
    for source_id in own:
        match = pylsl.resolve_byprop("source_id", source_id, 1, OWN_STREAMS_S)
        if not match:
            raise RecorderError(f"the session's own LSL stream {source_id!r} could not be found to "
                                "record (is LSL's multicast blocked on this machine?)")
        found.append(match[0])
    lab = pylsl.resolve_streams(settings.resolve_s) if settings.streams else []
    missing = []
    for wanted in settings.streams:
        matches = [info for info in lab if wanted in (info.name(), info.type())]
        found += [info for info in matches if info.uid() not in {f.uid() for f in found}]
        if not matches:
            missing.append(wanted)
    return found, missing


class _EngineProcess:
    """LabRecorder's engine in its own process (:mod:`app.session.xdf_engine`)."""

    def __init__(self, path: Path, streams: list[pylsl.StreamInfo]) -> None:
        if importlib.util.find_spec("labrecorder") is None:
            raise RecorderError("[recording] kind = \"labrecorder\" needs LabRecorder's engine: "
                                "pip install 'handover-lab[record]'")
        self._log = path.with_suffix(".log").open("a")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "app.session.xdf_engine"], stdin=subprocess.PIPE,
            stdout=self._log, stderr=subprocess.STDOUT, text=True, start_new_session=True)
        assert self.process.stdin is not None, "opened with a pipe"
        self.process.stdin.write(json.dumps({"path": str(path),
                                             "streams": [s.as_xml() for s in streams]}) + "\n")
        self.process.stdin.flush()

    def ended(self) -> int | None:
        return self.process.poll()

    def stop(self) -> None:
        assert self.process.stdin is not None, "opened with a pipe"
        try:
            self.process.stdin.write("stop\n")
            self.process.stdin.close()
        except BrokenPipeError:
            pass  # it ended already; its exit code says how
        try:
            self.process.wait(CLOSE_S)
        except subprocess.TimeoutExpired:
            log.error("the recording engine did not close the file within %g s: killed (the file "
                      "keeps what it wrote, without footers)", CLOSE_S)
            self.process.kill()
            self.process.wait()
        self._log.close()


class SessionRecording:
    """One run of one participant's recording (see the module's docstring)."""

    def __init__(self, settings: RecordingSettings, study: Path, code: str, own: list[str],
                 notify: Callable[[str], None]) -> None:
        self.settings, self._notify = settings, notify
        run = next_run(study, code)
        self.path = recording_path(study, code, settings.task, run)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        streams, missing = resolve_streams(settings, own)
        for name in missing:
            log.warning("[recording] streams names %r, but no LSL stream of that name or type was "
                        "found: it is not recorded", name)
        names = [s.name() for s in streams]
        self._status = RecordingStatus(kind=settings.kind, path=str(self.path), run=run,
                                       streams=names, missing=missing)
        self._engine: _EngineProcess | None = None
        self._remote: RemoteLabRecorder | None = None
        started = time.monotonic()
        try:
            if settings.kind == "labrecorder":
                self._engine = _EngineProcess(self.path, streams)
            else:
                self._remote = RemoteLabRecorder(settings.rcs_host, settings.rcs_port)
                self._remote.start(recordings_root(study).resolve(), code, settings.task, run)
            self._await_file(started)
        except RecorderError:
            self._stop_recorder()  # whatever of it started: a file it makes later is not this run's
            raise
        self._streaming = False  # a trial is streaming (set by the engine thread's listener)
        self._last_event = time.monotonic()  # when the last marker was pushed (engine thread)
        self._stopping = threading.Event()
        self._watch = threading.Thread(target=self._run, name="recording-watch", daemon=True)
        self._watch.start()
        log.info("recording %s into %s (streams %s)", settings.kind, self.path, names)

    def status(self) -> RecordingStatus:
        """The recording now (any thread)."""
        return self._status

    def _await_file(self, started: float) -> None:
        """Wait until the file exists: neither recorder says whether it records."""
        deadline = started + self.settings.start_timeout_s
        while not self.path.exists():
            ended = self._engine.ended() if self._engine is not None else None
            if ended is not None:
                raise RecorderError(f"the recording engine ended (exit code {ended}) before it made "
                                    f"{self.path.name}: see {self.path.with_suffix('.log')}")
            if time.monotonic() > deadline:
                who = "LabRecorder answered OK" if self._remote is not None else "the engine started"
                raise RecorderError(
                    f"{who}, but no file {self.path} appeared within "
                    f"{self.settings.start_timeout_s:g} s: the session is not being recorded "
                    "(is LabRecorder's study root this folder, and are its streams found?)")
            time.sleep(WATCH_S / 5)

    # -- on the engine thread ------------------------------------------------------------------
    def on_event(self, event: ev.ProtocolEvent, state: SessionState) -> None:
        """An engine listener: a trial streams robot samples from its Go to its end."""
        self._last_event = time.monotonic()
        if isinstance(event, ev.TrialStage) and event.stage == Stage.GO:
            self._streaming = True
        elif isinstance(event, ev.TrialEnded):
            self._streaming = False

    def close(self) -> None:
        """Stop the recording (the file keeps everything the recorder pulled) and the watch, once
        the recorder has pulled the session's last marker."""
        time.sleep(max(0.0, self._last_event + LAST_PULL_S - time.monotonic()))
        self._stopping.set()
        # bounded: the watch publishes news (the publishing lock), and this runs on the engine
        # thread, which a screen holding that lock may wait for; it only reads the file's size, so
        # the recorder may stop under it
        self._watch.join(WATCH_JOIN_S)
        self._stop_recorder()
        self._status = self._status.model_copy(update={"stopped": True,
                                                       "size": self._size()})
        log.info("recording %s stopped (%d bytes)", self.path, self._status.size)

    def _stop_recorder(self) -> None:
        if self._engine is not None:
            self._engine.stop()
        if self._remote is not None:
            try:
                self._remote.stop()
            except RecorderError as exc:
                log.error("stopping the lab's LabRecorder failed: %s", exc)

    # -- on the watch thread -------------------------------------------------------------------
    def _size(self) -> int:
        try:
            return self.path.stat().st_size
        except FileNotFoundError:
            return 0

    def _run(self) -> None:
        grew_at, size = time.monotonic(), self._size()
        while not self._stopping.wait(WATCH_S):
            now, latest = time.monotonic(), self._size()
            grew = latest != size
            if grew or not self._streaming:
                grew_at, size = now, latest
            if now - grew_at > self.settings.stall_s and self._status.warning is None:
                warning = (f"the recording stopped growing: {self.path.name} has not grown for "
                           f"{now - grew_at:.1f} s while a trial streams (at {size} bytes)")
                self._publish(latest, warning)
                self._notify(f"⚠ {warning}")
            elif grew:
                if self._status.warning is not None:
                    self._notify(f"the recording grows again ({self.path.name})")
                self._publish(latest, None)

    def _publish(self, size: int, warning: str | None) -> None:
        self._status = self._status.model_copy(update={"size": size, "warning": warning})
