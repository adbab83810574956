"""Who may use the screens: the dashboard's token (kept with the study) and rate-limited secrets.

* The dashboard token is stored in the study folder (``.dashboard-token``, readable by its owner
  only), so restarting ``handover serve`` keeps the experimenter's token; ``--token`` overrides it
  (and is not stored).
* :class:`KnownBrowsers`: the browsers (by the random id their page keeps, app/ui/client_page.py)
  in which the dashboard was unlocked or the tablet paired, kept in the study folder so that a
  restart of ``handover serve`` asks neither again. Only a hash of each id is stored, salted with
  what it stands for (the dashboard's token: a new token forgets every unlocked browser).
* Files in the study folder that decide who may do what (the token, the known browsers) are written
  owner-only (mode 600) and atomically, and one that is a symbolic link or that others may write is
  refused (:class:`UnsafeTokenFile`), not read: whoever can write it decides who moves the arm.
  ``serve`` checks them all before it serves a page (:func:`check_access_files`); a known-browsers
  file planted while it serves is read as no browser (every page gets its token or code screen) and
  replaced by the next browser remembered.
* :class:`AttemptLimit` counts the wrong tries of a secret (the dashboard token, the tablet's
  pairing code) per remote address, each logged with its address: ``max_failures`` per
  ``window_s`` are free; past them the tablet's code is refused unchecked until the window has slid
  past the oldest, and the dashboard's token waits before it is checked (longer with each wrong
  one), so that others on the experimenter's address cannot lock the right token out.
"""

from __future__ import annotations

import hashlib
import logging
import os
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

log = logging.getLogger(__name__)

#: The dashboard token's file in the study folder.
TOKEN_FILE = ".dashboard-token"
#: The browsers in which the dashboard was unlocked, and the one in which the tablet was paired.
DASHBOARD_BROWSERS_FILE = ".dashboard-browsers"
TABLET_BROWSER_FILE = ".tablet-browser"
#: How many unlocked dashboard browsers are remembered (the latest).
KNOWN_DASHBOARDS = 20


class UnsafeTokenFile(ValueError):
    """A file of the study's that decides access could have been written by someone else: refused,
    not read."""


def read_private(path: Path) -> str | None:
    """The text of an access file of the study (None if there is none); refused
    (:class:`UnsafeTokenFile`) if it is a symbolic link or others may write it."""
    if path.is_symlink():
        raise UnsafeTokenFile(f"{path} is a symbolic link: refused (delete it; serve makes a new "
                              "one)")
    if not path.exists():
        return None
    if (mode := path.stat().st_mode & 0o777) & 0o022:
        raise UnsafeTokenFile(f"{path} is writable by others (mode {mode:o}): refused, as anyone "
                              "could choose who uses the screens (chmod 600 it, or delete it and "
                              "serve makes a new one)")
    return path.read_text()


def write_private(path: Path, text: str) -> None:
    """Write an access file of the study: owner-only, atomically (a crash leaves the old file or the
    new one, never half of one)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    partial.unlink(missing_ok=True)  # O_EXCL below: never write through a link planted here
    descriptor = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "w") as out:
        out.write(text)
        out.flush()
        os.fsync(out.fileno())
    partial.replace(path)


def dashboard_token(study: Path, override: str | None = None) -> str:
    """``override`` if given; else the study's stored token, created (random) on first use. A token
    file that is a symbolic link, or that others may write, is refused (:class:`UnsafeTokenFile`):
    whoever can write it chooses the token of the dashboard that moves the arm. One that others may
    read is made owner-only, as the writer's lock file is, with a warning: whoever read it knows the
    token."""
    if override:
        return override
    path = Path(study) / TOKEN_FILE
    token = (read_private(path) or "").strip()
    if token and (mode := path.stat().st_mode & 0o777) & 0o077:
        try:
            path.chmod(0o600)
        except OSError as exc:
            raise UnsafeTokenFile(f"{path} is readable by others (mode {mode:o}) and this user "
                                  f"cannot make it owner-only ({exc.strerror}): chmod 600 it, or "
                                  "delete it and serve makes a new one") from None
        log.warning("%s was readable by others (mode %o): made owner-only (600). Anyone who read "
                    "it knows the token: delete it for a new one", path, mode)
    if not token:
        token = secrets.token_urlsafe(9)
        write_private(path, token + "\n")
    return token


def check_access_files(study: Path) -> None:
    """Refuse (:class:`UnsafeTokenFile`, naming the file and what to do) a study whose known-browser
    files are symbolic links or writable by others, before any page is served: read while serving,
    they would fail every page's start."""
    for name in (DASHBOARD_BROWSERS_FILE, TABLET_BROWSER_FILE):
        read_private(Path(study) / name)


class KnownBrowsers:
    """Browser ids remembered in the study folder's ``file`` (the latest ``keep``), each stored as
    the hash of ``salt`` and the id (thread-safe)."""

    def __init__(self, study: Path, file: str, salt: str = "", keep: int = 1) -> None:
        self.path, self.salt, self.keep = Path(study) / file, salt, keep
        self._lock = threading.Lock()

    def _hash(self, browser: str) -> str:
        return hashlib.sha256(f"{self.salt}\n{browser}".encode()).hexdigest()

    def _stored(self) -> list[str]:
        """The stored hashes; none from a file planted since the start (:func:`check_access_files`):
        it grants nothing, and the next :meth:`remember` replaces it."""
        try:
            return (read_private(self.path) or "").split()
        except UnsafeTokenFile as exc:
            log.error("%s; no browser is known by it until one is remembered anew", exc)
            return []

    def known(self, browser: str | None) -> bool:
        if browser is None:
            return False
        with self._lock:
            return self._hash(browser) in self._stored()

    def remember(self, browser: str | None) -> None:
        if browser is None:
            return
        with self._lock:
            digest = self._hash(browser)
            stored = [d for d in self._stored() if d != digest] + [digest]
            write_private(self.path, "\n".join(stored[-self.keep:]) + "\n")


#: Wrong tries past the free ones make each further try from that address wait: FIRST_WAIT_S for
#: the first, doubled with each wrong one, at most MAX_WAIT_S [s].
FIRST_WAIT_S, MAX_WAIT_S = 1.0, 8.0


class AttemptLimit:
    """Checks of a secret, per remote address (thread-safe): ``max_failures`` wrong ones per
    ``window_s`` are free; past them, :meth:`check` refuses the address's tries unchecked (the
    tablet's code, which is replaced after CODE_GUESSES wrong ones anyway), while :meth:`wait_s`
    says how long a try should wait before :meth:`judge` checks it (the dashboard's token: a right
    token is never refused, only slowed down with the wrong ones around it)."""

    def __init__(self, max_failures: int = 5, window_s: float = 60.0,
                 clock: Callable[[], float] = time.monotonic, what: str = "code",
                 role: str = "tablet") -> None:
        self.max_failures, self.window_s, self._clock = max_failures, window_s, clock
        self.what, self.role = what, role
        self._failures: dict[str, deque[float]] = {}
        self._lock = threading.Lock()
        self.refused_unchecked = 0
        #: every wrong attempt so far
        self.wrong = 0

    def _recent(self, source: str, now: float) -> deque[float]:
        """``source``'s wrong tries within the window (under the lock)."""
        failures = self._failures.setdefault(source, deque())
        while failures and now - failures[0] >= self.window_s:
            failures.popleft()
        return failures

    def recent(self, source: str) -> int:
        """How many wrong tries ``source`` made within the window."""
        with self._lock:
            return len(self._recent(source, self._clock()))

    def wait_s(self, source: str) -> float:
        """How long a try from ``source`` waits before it is checked: 0 while its wrong tries in the
        window are fewer than ``max_failures``, then FIRST_WAIT_S doubled with each further one, at
        most MAX_WAIT_S."""
        beyond = self.recent(source) - self.max_failures
        return 0.0 if beyond < 0 else min(FIRST_WAIT_S * 2.0 ** beyond, MAX_WAIT_S)

    def check(self, source: str, given: str, secret: str) -> str | None:
        """None if ``given`` is ``secret``; otherwise why not, for the screen: past ``max_failures``
        wrong tries in the window, refused unchecked until the window slides past the oldest."""
        now = self._clock()
        with self._lock:
            failures = self._recent(source, now)
            if len(failures) >= self.max_failures:
                self.refused_unchecked += 1
                wait = self.window_s - (now - failures[0])
                if self.refused_unchecked == 1 or self.refused_unchecked % 100 == 0:
                    log.warning("%s: %s attempts from %s refused unchecked (%d wrong in %g s; "
                                "%d refused so far)", self.role, self.what, source, len(failures),
                                self.window_s, self.refused_unchecked)
                return f"Too many wrong attempts from this address: try again in {wait:.0f} s."
        refusal = self.judge(source, given, secret)
        if refusal is None:
            with self._lock:
                self._recent(source, now).clear()  # a typo before the right code is no guessing
        return refusal

    def judge(self, source: str, given: str, secret: str) -> str | None:
        """None if ``given`` is ``secret``; otherwise "Wrong …", counted and logged with its
        address."""
        now = self._clock()
        with self._lock:
            failures = self._recent(source, now)
            if secrets.compare_digest(given.encode(), secret.encode()):
                log.info("%s: %s accepted from %s", self.role, self.what, source)
                return None
            failures.append(now)
            self.wrong += 1
            log.warning("%s: wrong %s from %s (%d in %g s; %d free)", self.role, self.what,
                        source, len(failures), self.window_s, self.max_failures)
            return f"Wrong {self.what}."
