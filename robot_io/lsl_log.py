"""liblsl's log on the experimenter's terminal: warnings and errors only, unless asked for.

liblsl logs from C to stderr, at INFO by default ("Loaded default config", its build, …), in every
process that uses it. Its level is read from its configuration file when it first needs it: the
file named by ``LSLAPICFG``, else ``lsl_api.cfg`` in the working folder, ``~/lsl_api/`` or
``/etc/lsl_api/``. A lab that has such a file keeps it (it may hold the lab's network settings and
its own ``[log] level``); otherwise ``LSLAPICFG`` names :data:`QUIET_CONFIG` (``[log] level = -1``,
warnings and errors), which the processes the command starts inherit.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The configuration used when the lab has none: liblsl's warnings and errors only.
QUIET_CONFIG = Path(__file__).with_name("lsl_api_quiet.cfg")
#: Where liblsl looks for a lab's own configuration when ``LSLAPICFG`` is not set, in its order.
LAB_CONFIGS = (Path("lsl_api.cfg"), Path.home() / "lsl_api" / "lsl_api.cfg",
               Path("/etc/lsl_api/lsl_api.cfg"))


def quiet_liblsl() -> None:
    """liblsl logs warnings and errors only in this process and the ones it starts, unless the lab
    configures liblsl itself. Call it before liblsl is first used."""
    if "LSLAPICFG" in os.environ or any(path.is_file() for path in LAB_CONFIGS):
        return
    os.environ["LSLAPICFG"] = str(QUIET_CONFIG)
