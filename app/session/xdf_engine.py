"""LabRecorder's recording engine (the ``labrecorder`` package) in a process of its own:
``python -m app.session.xdf_engine`` records the streams it is given into one XDF file until it
reads ``stop`` or its standard input closes (the session ended, or the application died), then
stops the engine, which writes every stream's footer and closes the file.

Its own process, because the engine writes its progress to the standard output of the process it
runs in (the session's own output, e.g. ``run-session --json``, must stay the session's; here it
goes to a log file beside the recording), because a fault of the C++ engine then ends this process,
not the session, and because closing the file takes it seconds (it joins its clock-offset threads),
which no thread of the session waits for. A kill of this process leaves the file without footers:
pyxdf reads every chunk written before it (docs/hardware.md, "The session's own recording").

Standard input, one JSON line first: ``{"path": FILE, "streams": [stream XML, ...]}`` (each
stream's ``pylsl.StreamInfo.as_xml()``; the engine resolves it again by its uid).
"""

from __future__ import annotations

import json
import signal
import sys


def main() -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the session's: it stops this by stdin
    request = json.loads(sys.stdin.readline())
    import labrecorder  # the 'record' extra; imported here so that a missing one is this process's exit

    recording = labrecorder.Recording(request["path"], request["streams"])
    print(f"recording {len(request['streams'])} streams into {request['path']}", flush=True)
    for line in sys.stdin:
        if line.strip() == "stop":
            break
    recording.stop()
    del recording  # the engine joins its threads and writes the footers as it is destroyed
    print("closed", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
