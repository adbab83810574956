"""The study's own XDF recordings in the report (``[recording]``, issue 47): ``handover report``
finds each participant's runs in the study folder (:mod:`session_store.recordings`) with no
``--xdf``, lists their streams and sample counts, and checks that every stored trial that reached
its Go has its ``go`` marker in one of them — naming those that do not (a recording that stopped, a
run that was never recorded)."""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import partial
from pathlib import Path

import pandas as pd

from app.analysis import html
from app.analysis.xdf import WholeChunks, XDFError, decoded_markers, readable
from app.protocol.markers import MARKER_TYPE
from session_store.recordings import recordings_of

COLUMNS = ["participant", "file", "bytes", "stream", "type", "samples", "footer"]


def _load(load_xdf: Callable[..., tuple[list[dict], dict]], whole: WholeChunks) -> list[dict]:
    return load_xdf(whole.open())[0]


def _ours(stream: dict, code: str, created_at: str) -> bool:
    """Whether ``stream`` is the marker stream of participant ``code``'s session created at
    ``created_at``: its ``source_id`` names both (app/session/lsl_outlets.py). A LabRecorder told to
    ``select all`` records every session's streams it sees, another study's P01 too."""
    info = stream["info"]
    return info["type"][0] == MARKER_TYPE and \
        info["source_id"][0].endswith(f":{code}:{created_at}")


def recorded_runs(study_dir: Path, sessions: dict[str, str]) -> tuple[pd.DataFrame,
                                                                     dict[str, set[int]], list[str]]:
    """Every stream of every run of the participants ``sessions`` (code → when their session was
    created): participant, run file, stream, type, samples, footer (whether the recorder closed
    it); the trials whose ``go`` marker each participant's runs hold, and what could not be read,
    in words that name the file (all of it, a chunk left out, a marker torn in the middle)."""
    rows: list[dict] = []
    found: dict[str, set[int]] = {}
    problems: list[str] = []
    runs = {code: recordings_of(study_dir, code) for code in sessions}
    if not any(runs.values()):
        return pd.DataFrame(rows, columns=COLUMNS), found, problems
    try:
        import pyxdf
    except ImportError:
        return (pd.DataFrame(rows, columns=COLUMNS), found,
                ["reading the study's recordings needs pyxdf: pip install 'handover-lab[xdf]'"])
    for code, paths in runs.items():
        found[code] = set()
        for path in paths:
            try:
                whole = readable(path, partial(WholeChunks.of, path))
                streams: list[dict] = readable(path, partial(_load, pyxdf.load_xdf, whole))
            except XDFError as exc:
                problems.append(str(exc))
                continue
            problems += [f"{path}: {why}" for why in whole.left_out]
            for stream in streams:
                rows.append({"participant": code, "file": path.name,
                             "bytes": path.stat().st_size, "stream": stream["info"]["name"][0],
                             "type": stream["info"]["type"][0],
                             "samples": len(stream["time_stamps"]),
                             "footer": bool(stream.get("footer"))})
                if _ours(stream, code, sessions[code]):
                    try:
                        markers, torn = decoded_markers(path, stream)
                    except XDFError as exc:
                        problems.append(str(exc))
                        continue
                    problems += [f"{path}: {why}" for why in torn]
                    found[code] |= {marker["trial"] for _, marker in markers if marker["event"] == "go"}
    return pd.DataFrame(rows, columns=COLUMNS), found, problems


def stored_gos(events: pd.DataFrame) -> dict[str, set[int]]:
    """participant → the trials whose Go the study stored (a ``trial_stage`` event ``go``)."""
    gos: dict[str, set[int]] = {}
    for code, payload in events.loc[events["kind"] == "trial_stage",
                                    ["participant", "payload"]].itertuples(index=False):
        stage = json.loads(payload)
        if stage["stage"] == "go":
            gos.setdefault(code, set()).add(int(stage["trial_index"]))
    return gos


def go_check(stored: dict[str, set[int]], recorded: dict[str, set[int]]) -> pd.DataFrame:
    """Per participant with recordings: stored Go markers found in them, and those missing."""
    rows = [{"participant": code, "stored_gos": len(stored.get(code, set())),
             "recorded": len(stored.get(code, set()) & found),
             "missing": ", ".join(map(str, sorted(stored.get(code, set()) - found)))}
            for code, found in recorded.items()]
    return pd.DataFrame(rows, columns=["participant", "stored_gos", "recorded", "missing"])


def recordings_section(runs: pd.DataFrame, check: pd.DataFrame, problems: list[str]) -> str:
    """The report page's "Recordings" section (empty without recordings)."""
    if runs.empty and not problems:
        return ""
    verdicts = [f"{row.participant}: every stored trial's Go marker is in the recording "
                f"({row.recorded} of {row.stored_gos})" if not row.missing else
                f"{row.participant}: {row.recorded} of {row.stored_gos} Go markers recorded; "
                f"trials {row.missing} are not in any recording"
                for row in check.itertuples()]
    return html.section(
        "Recordings", html.paragraph(
            "The session's own XDF recordings (lab.toml [recording]) found in the study folder, "
            "one file per participant and run: their streams and sample counts, and whether each "
            "trial stored with a Go has its go marker in them."),
        html.items(verdicts + problems),  # each names its file and says what was not read
        html.table(runs, {c: c for c in runs.columns}))
