"""A stand-in for LabRecorder's remote control (its GUI's "EnableRCS" socket, TCP port 22345), for
rehearsals and tests where the GUI is not installed, written from LabRecorder's documented commands
and its source (``src/tcpinterface.cpp``, ``src/mainwindow.cpp``).

As LabRecorder does: one command a line; ``OK`` (two bytes, no newline) to every line, known or
not, before anything is done; ``select all`` / ``select none`` / ``update``; ``filename`` with
``{option:value}`` options (``root``, ``template`` — lower-cased, and it turns the BIDS template off,
so the run is ``%n`` — ``task`` %b, ``run`` %n/%r, ``participant`` %p, ``session`` %s,
``acquisition`` %a, ``modality`` %m; the run written with three digits); ``start`` selects every
stream, resolves the streams on the network (1 s) and records them all with LabRecorder's own
engine (the ``labrecorder`` package) into root/template, moving an existing file aside to ``_old1``; ``stop``
ends the recording. ``silent = True`` makes the faulty recorder the session must catch: it answers
OK to everything and records nothing. ``sees`` narrows "the network" to the streams its owner
lets it see (a test's own, while other tests' streams come and go on the same machine).

The engine records in a process of its own (:func:`_record`): destroying it joins its threads while
it holds the interpreter lock, and a thread stuck on a stream that vanished froze every thread of
the process that held it (a test run, for good); a recording that does not close within
``CLOSE_S`` is killed (the file keeps what was written, without footers).

    python -m robot_io.standins.labrecorder_rcs [--port 22345] [--silent]
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import multiprocessing
import re
import socketserver
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

import pylsl

log = logging.getLogger(__name__)

#: How long a recording may take to close its file after ``stop`` [s] (the engine joins its
#: clock-offset threads, up to 5 s each) before it is killed.
CLOSE_S = 15.0

OPTION = re.compile(r"{(?P<option>\w+?):(?P<value>[^}]*)}")
#: LabRecorder's BIDS template, used until a ``template`` option replaces it.
BIDS_TEMPLATE = "sub-%p/ses-%s/%m/sub-%p_ses-%s_task-%b[_acq-%a]_run-%r_%m.xdf"


class StandInLabRecorder:
    """LabRecorder's state behind its remote control (the GUI's fields)."""

    def __init__(self, silent: bool = False, echo: bool = False,
                 sees: Callable[[pylsl.StreamInfo], bool] | None = None) -> None:
        self.silent, self.echo = silent, echo  # echo: print each command with its Unix time
        self.sees = sees  # None: every stream on the network, as LabRecorder's list
        self.fields = {"root": "", "template": BIDS_TEMPLATE, "task": "Default", "run": "1",
                       "participant": "P001", "session": "S001", "acquisition": "", "modality": "eeg"}
        self.bids = True
        self.lines: list[str] = []  # every command received, in order
        self.recording: Recording | None = None
        self.path: Path | None = None
        self._lock = threading.Lock()

    def handle(self, line: str) -> None:
        with self._lock:
            self.lines.append(line)
            if self.echo:
                print(f"{time.time():.3f} {line}", flush=True)
            if line == "start":
                self._start()
            elif line == "stop":
                self._stop()
            elif "filename" in line:
                for match in OPTION.finditer(line):
                    option, value = match.group("option").lower(), match.group("value")
                    if option == "template":
                        self.bids, value = False, value.lower()
                    self.fields[option] = value

    def filename(self) -> Path:
        """The file a start records into: root/template with the placeholders replaced."""
        template = self.fields["template"]
        if self.bids:
            template = template.replace("[_acq-%a]", "_acq-%a" if self.fields["acquisition"] else "")
        name = template.replace("%b", self.fields["task"]).replace("%p", self.fields["participant"])
        name = name.replace("%s", self.fields["session"]).replace("%a", self.fields["acquisition"])
        name = name.replace("%m", self.fields["modality"])
        name = name.replace("%r" if self.bids else "%n", f"{int(self.fields['run'] or 0):03d}")
        return Path(self.fields["root"]) / name

    def _start(self) -> None:
        if self.recording is not None or self.silent:
            return
        path = self.filename()
        if path.exists():
            index = 1
            while (aside := path.with_name(f"{path.stem}_old{index}{path.suffix}")).exists():
                index += 1
            path.rename(aside)
        path.parent.mkdir(parents=True, exist_ok=True)
        streams = [info for info in pylsl.resolve_streams(1.0)  # a start selects every stream
                   if self.sees is None or self.sees(info)]
        self.path, self.recording = path, Recording(path, streams)

    def _stop(self) -> None:
        if self.recording is not None:
            self.recording.close()
            self.recording = None


class Recording:
    """LabRecorder's engine recording ``streams`` into ``path`` in a process of its own (spawned);
    :meth:`close` stops it and waits until the file is closed (killed after ``CLOSE_S``)."""

    def __init__(self, path: Path, streams: list[pylsl.StreamInfo]) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self.process = context.Process(target=_record, name="labrecorder-standin-engine",
                                       args=(str(path), [info.as_xml() for info in streams], child),
                                       daemon=True)
        self.process.start()
        child.close()
        self._conn.recv()  # recording (or EOFError: the engine could not start)

    def close(self) -> None:
        with contextlib.suppress(OSError):  # it ended already
            self._conn.send("stop")
        self.process.join(CLOSE_S)
        if self.process.is_alive():
            log.error("the stand-in's recording did not close its file within %g s: killed",
                      CLOSE_S)
            self.process.kill()
            self.process.join()
        self._conn.close()
        self.process.close()


def _record(path: str, streams: list[str], conn: Connection) -> None:
    """The engine's process: record until told to stop (or the pipe closes), then close the file
    (the engine writes its footers as it is destroyed)."""
    import labrecorder  # LabRecorder's engine (the 'record' extra)

    recording = labrecorder.Recording(path, streams)
    conn.send("recording")
    with contextlib.suppress(EOFError):  # the stand-in has gone: stop as told
        conn.recv()
    recording.stop()
    del recording


class _Handler(socketserver.StreamRequestHandler):
    server: RemoteControl

    def handle(self) -> None:
        for raw in self.rfile:
            self.server.recorder.handle(raw.decode(errors="replace").strip())
            self.wfile.write(b"OK")


class RemoteControl(socketserver.ThreadingTCPServer):
    """The remote control socket on ``port`` (0: a free one; :attr:`port` says which)."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, recorder: StandInLabRecorder, port: int = 0, host: str = "127.0.0.1") -> None:
        super().__init__((host, port), _Handler)
        self.recorder = recorder
        self.port = self.server_address[1]
        self._thread = threading.Thread(target=self.serve_forever, name="labrecorder-rcs", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.shutdown()
        self.server_close()
        self.recorder.handle("stop")


def main() -> None:
    parser = argparse.ArgumentParser(description="A stand-in for LabRecorder's remote control.")
    parser.add_argument("--port", type=int, default=22345)
    parser.add_argument("--silent", action="store_true", help="answer OK and record nothing")
    args = parser.parse_args()
    server = RemoteControl(StandInLabRecorder(args.silent, echo=True), args.port)
    print(f"LabRecorder stand-in: remote control on 127.0.0.1:{server.port}"
          + (" (silent: records nothing)" if args.silent else ""), flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        server.close()


if __name__ == "__main__":
    main()
