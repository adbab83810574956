"""Output never fails a command that did its work: with stdout and stderr in ASCII (``LANG=C``,
``PYTHONIOENCODING=ascii``), a completed session exits 0 and says θ* as an escape, and ``report``
writes its report (before, both exited 2 on "θ" and "–" once their work was done)."""

from __future__ import annotations

import os
import subprocess
import sys

from support.engine import BRIEF_PROTOCOL, SESSION_LOOP_TOML, protocol_toml
from support.waiting import CEILING_S

ASCII = {**os.environ, "LANG": "C", "LC_ALL": "C", "PYTHONIOENCODING": "ascii"}


def handover(*arguments: str) -> subprocess.CompletedProcess:
    # A ceiling for a hung command, not a measurement.
    return subprocess.run([sys.executable, "-m", "app.cli", *arguments], env=ASCII, text=True,
                          encoding="ascii", capture_output=True, timeout=CEILING_S * 5)


def test_an_ascii_terminal_gets_escapes_not_a_failed_command(tmp_path):
    """Slow (~25 s in a loaded full run): a whole session of the brief protocol and a report, each
    a fresh `handover` process on an ASCII terminal, as a lab's old terminal would run them."""
    lab = tmp_path / "lab.toml"
    lab.write_text(f"{SESSION_LOOP_TOML}\n[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}")
    study = tmp_path / "study"
    session = handover("run-session", "--study", str(study), "--participant", "A1", "--scenario",
                       "perturbed", "--auto", "--seed", "3", "--no-progress", "--config", str(lab))
    assert session.returncode == 0, session.stderr
    assert "\\u03b8* = (a " in session.stdout  # θ*, escaped
    report = handover("report", str(study), "--out", str(tmp_path / "report"))
    assert report.returncode == 0, report.stderr
    assert (tmp_path / "report" / "report.html").is_file()


#: Run as ``python -c``: a Ctrl-C that lands while the command's own modules load, before the
#: session has put its handler in place (an import hook raises it where the signal would).
CTRL_C_WHILE_LOADING = """
import sys

class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == "app.session.run_session":
            raise KeyboardInterrupt
        return None

sys.meta_path.insert(0, CtrlC())
from app.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_while_the_command_loads_ends_it_with_130_and_no_traceback(tmp_path):
    """Ctrl-C 1.6 s after ``run-session`` started printed a KeyboardInterrupt traceback (issue 44's
    interrupted sessions): a close, however early, prints a sentence, not a traceback."""
    ended = subprocess.run([sys.executable, "-c", CTRL_C_WHILE_LOADING, "run-session", "--study",
                            str(tmp_path / "study"), "--participant", "P01", "--scenario",
                            "perturbed", "--auto"], env=ASCII, text=True, capture_output=True,
                           timeout=CEILING_S * 5)
    assert ended.returncode == 130, ended.stderr
    assert "Traceback" not in ended.stderr + ended.stdout, ended.stderr
    assert ended.stderr.strip() == "handover run-session: interrupted (Ctrl-C)"
    assert not (tmp_path / "study" / "P01.sqlite").exists()
