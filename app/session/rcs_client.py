"""The lab's LabRecorder, driven over its remote control socket (``[recording] kind =
"labrecorder_rcs"``; LabRecorder's "EnableRCS", TCP port 22345 by default).

LabRecorder takes one command a line — ``select all``, ``select none``, ``update``, ``start``,
``stop``, ``filename {option:value} ...`` (options ``root``, ``template``, ``task``, ``run``,
``participant``, ``session``, ``acquisition``, ``modality``) — and answers ``OK`` to every line,
known or not, before it has done anything: its answer says nothing of the recording. So the
session checks for itself that the file appears and grows (:mod:`app.session.recording`).
"""

from __future__ import annotations

import socket
from pathlib import Path

from session_store.recordings import MODALITY, SESSION, TEMPLATE

#: How long a connection and an answer may take [s].
ANSWER_S = 2.0
#: LabRecorder answers a command only once it has carried it out, on its GUI's thread: ``start``
#: first looks for the streams on the network (1 s), ``stop`` closes the file (its threads join: up
#: to ~5 s, more on a loaded machine) [s].
ANSWER_AFTER_S = {"start": 10.0, "stop": 30.0}


class RecorderError(RuntimeError):
    """The recorder could not be reached, or did not record: the message says which and why."""


class RemoteLabRecorder:
    """One connection to LabRecorder's remote control at ``host``:``port``."""

    def __init__(self, host: str, port: int) -> None:
        self.where = f"LabRecorder's remote control at {host}:{port}"
        try:
            self._socket = socket.create_connection((host, port), timeout=ANSWER_S)
        except ConnectionRefusedError as exc:
            raise RecorderError(f"{self.where} refused the connection: is LabRecorder running with "
                                "'EnableRCS' checked on that port ([recording] rcs_port)?") from exc
        except TimeoutError as exc:
            raise RecorderError(f"{self.where} did not accept a connection within {ANSWER_S:g} s "
                                "(a firewall, or the wrong host: [recording] rcs_host)") from exc
        except OSError as exc:
            raise RecorderError(f"{self.where} cannot be reached: {exc}") from exc

    def command(self, line: str) -> None:
        """Send one command and read LabRecorder's ``OK`` (which it sends whatever the command)."""
        patience = ANSWER_AFTER_S.get(line, ANSWER_S)
        try:
            self._socket.settimeout(patience)
            self._socket.sendall(line.encode() + b"\n")
            answer = b""
            while len(answer) < 2:
                chunk = self._socket.recv(2 - len(answer))
                if not chunk:
                    raise RecorderError(f"{self.where} closed the connection after {line!r}")
                answer += chunk
        except TimeoutError as exc:
            raise RecorderError(f"{self.where} did not answer {line!r} within {patience:g} s") from exc
        except OSError as exc:
            raise RecorderError(f"{self.where} failed on {line!r}: {exc}") from exc
        if answer != b"OK":
            raise RecorderError(f"{self.where} answered {answer!r} to {line!r}, not OK: is it "
                                "LabRecorder?")

    def start(self, root: Path, code: str, task: str, run: int) -> None:
        """Record every stream LabRecorder sees (``select all``) into ``root`` under the study's
        BIDS-style name (:func:`session_store.recordings.recording_path`). A ``stop`` first: a
        LabRecorder still recording ignores ``start`` (and the new file name), and it still records
        the run of a session that crashed (a stop while it records nothing does nothing)."""
        if "}" in str(root):
            raise RecorderError(f"the recordings folder {root} holds '}}', which LabRecorder's "
                                "filename command cannot carry")
        self.command("stop")
        self.command("select all")
        self.command(f"filename {{root:{root}}} {{template:{TEMPLATE}}} {{participant:{code}}} "
                     f"{{session:{SESSION}}} {{task:{task}}} {{modality:{MODALITY}}} {{run:{run}}}")
        self.command("start")

    def stop(self) -> None:
        try:
            self.command("stop")
        finally:
            self._socket.close()
