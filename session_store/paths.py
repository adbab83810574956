"""Where a study keeps its participants: ``<study>/<code>.sqlite``, the code a safe file name.

Imports nothing heavy: the command line resolves a participant's database (and takes its writer
lock) through it before loading the rest of the application.
"""

from __future__ import annotations

import errno
import os
import pwd
import re
from pathlib import Path

from session_store.errors import StoreError, UnsafeParticipantCode

SUFFIX = ".sqlite"
#: The study folder of ``handover serve`` when ``--study`` is not given.
DEFAULT_STUDY = Path("study")
#: The file formats of an export (session_store.export), one file per table.
EXPORT_FORMATS = ("csv", "parquet")
#: A participant code is pseudonymous and becomes a file name: letters, digits, '-' and '_' only.
CODE_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")


def check_participant_code(code: str) -> str:
    """Return ``code`` if it is a safe file name, else raise UnsafeParticipantCode saying why."""
    if not isinstance(code, str) or not CODE_PATTERN.fullmatch(code):
        shown = code if isinstance(code, str) and len(code) <= 40 else f"{str(code)[:40]}…"
        raise UnsafeParticipantCode(
            f"participant code {shown!r} is not allowed: use 1 to 64 letters, digits, '-' or '_', "
            "starting with a letter or digit (a pseudonym, never a name)")
    return code


def participant_path(study_dir: Path, code: str) -> Path:
    return Path(study_dir) / f"{check_participant_code(code)}{SUFFIX}"


def refuse_case_twin(study_dir: Path, code: str) -> None:
    """Refuse a new participant ``code`` that differs only in case from one of the study's: on a
    case-insensitive disk (macOS, Windows, most USB sticks) the two would be one file."""
    twin = next((other for other in participant_codes(study_dir)
                 if other != code and other.casefold() == code.casefold()), None)
    if twin is not None:
        raise StoreError(f"participant code {code!r} differs only in case from {twin!r} of this "
                         "study: on a case-insensitive disk (macOS, Windows, a USB stick) they would "
                         f"be one file. Resume {twin!r}, or choose another code")


def unreadable_study(study_dir: Path, exc: OSError) -> StoreError:
    """Why the study folder cannot be read, in a sentence: for a folder this user may not enter
    (another user's, mode 700), its owner and mode and what to do, rather than an empty folder or a
    traceback."""
    if exc.errno not in (errno.EACCES, errno.EPERM):
        return StoreError(f"cannot read the study folder {study_dir}: {exc.strerror or exc}")
    try:
        folder = os.stat(study_dir)
        owner = pwd.getpwuid(folder.st_uid).pw_name
    except (OSError, KeyError):  # the folder above it is closed too, or an owner without a name
        return StoreError(f"cannot read the study folder {study_dir}: permission denied (it, or a "
                          "folder above it, belongs to another user): run this as its owner, or "
                          "have them give this user read access to it")
    return StoreError(f"cannot read the study folder {study_dir}: permission denied (it belongs to "
                      f"{owner}, mode {folder.st_mode & 0o777:o}): run this as {owner}, or have "
                      f"{owner} give this user read access to it")


def participant_files(study_dir: Path) -> list[Path]:
    """The participant databases (``*.sqlite``) of a study folder, sorted by name; a folder this
    user cannot read is refused naming why (:func:`unreadable_study`), never read as empty."""
    try:
        names = os.listdir(study_dir)
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise unreadable_study(Path(study_dir), exc) from None
    return sorted(Path(study_dir) / name for name in names
                  if name.endswith(SUFFIX) and not name.startswith("."))


def participant_codes(study_dir: Path) -> list[str]:
    """Codes of the participant databases in a study folder, sorted."""
    return [path.stem for path in participant_files(study_dir)]
