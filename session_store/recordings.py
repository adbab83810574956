"""Where a study keeps the XDF recordings its sessions make (``[recording]``): one file per
participant and run, named the way LabRecorder's BIDS template names them,

    <study>/recordings/sub-<code>/ses-<session>/beh/sub-<code>_ses-<session>_task-<task>_run-<NNN>_beh.xdf

(LabRecorder writes the run with three digits). A resumed session records a new run. ``handover
report`` finds them here; the session's own recorder writes them and LabRecorder, driven over its
remote control, is told this folder and this template.
"""

from __future__ import annotations

import re
from pathlib import Path

from session_store.paths import check_participant_code

#: The study folder's subfolder of recordings.
RECORDINGS = "recordings"
#: The BIDS session label (a participant has one session, resumed as runs) and modality.
SESSION, MODALITY = "01", "beh"
#: LabRecorder's own template with its placeholders (%p participant, %s session, %b task, %n run,
#: %m modality): told over its remote control, it names the file the way :func:`recording_path` does.
TEMPLATE = "sub-%p/ses-%s/%m/sub-%p_ses-%s_task-%b_run-%n_%m.xdf"
_RUN = re.compile(r"_run-(\d+)_")


def recordings_root(study_dir: Path) -> Path:
    return Path(study_dir) / RECORDINGS


def recording_path(study_dir: Path, code: str, task: str, run: int) -> Path:
    """The file of ``code``'s run ``run``."""
    check_participant_code(code)
    name = f"sub-{code}_ses-{SESSION}_task-{task}_run-{run:03d}_{MODALITY}.xdf"
    return recordings_root(study_dir) / f"sub-{code}" / f"ses-{SESSION}" / MODALITY / name


def recordings_of(study_dir: Path, code: str) -> list[Path]:
    """``code``'s recordings, in run order."""
    folder = recordings_root(study_dir) / f"sub-{check_participant_code(code)}"
    found = [(int(m.group(1)), path) for path in folder.glob("ses-*/*/*.xdf")
             if (m := _RUN.search(path.name)) and path.name.startswith(f"sub-{code}_")]
    return [path for _, path in sorted(found)]


def next_run(study_dir: Path, code: str) -> int:
    """The run number of ``code``'s next recording: one past the highest recorded."""
    runs = [int(m.group(1)) for path in recordings_of(study_dir, code)
            if (m := _RUN.search(path.name))]
    return max(runs, default=0) + 1
