"""Write the bytecode of every module the project and its test suite import, before the suite runs.

Where ``PYTHONDONTWRITEBYTECODE`` is set (it is on the CI machine), no process writes a ``.pyc``, and
every process of the suite would compile torch, BoTorch, viser and the rest from source. Compiling
the whole environment at install (``uv pip install --compile-bytecode``) took 48 of the install's
54 s on 2 cores (13,161 files), most of them never imported. Instead, two processes import what
the suite imports — every module of the project's packages (with them torch, BoTorch, viser,
pandas, Dask, matplotlib) and the test tools — with the variable cleared, so Python writes the
``.pyc`` of exactly those modules (about 3,300 files); ``make test`` runs pytest with it cleared
too, so a module imported only later is compiled once, not in every process.

Usage: ``python .ci/bytecode.py`` (``make bytecode``).
"""

from __future__ import annotations

import os
import subprocess
import sys

#: What the suite imports, in two groups of about equal cost that run side by side: the learner's
#: (torch) and everything else. A module both import is compiled by both; they share little.
GROUPS = (
    "import pkgutil, app.learning\n"
    "for module in pkgutil.walk_packages(app.learning.__path__, 'app.learning.'):\n"
    "    __import__(module.name)\n"
    "import torch.fx.experimental.symbolic_shapes\n",
    "import pkgutil, importlib, app, robot_io, session_store\n"
    "for package in (app, robot_io, session_store):\n"
    "    for module in pkgutil.walk_packages(package.__path__, package.__name__ + '.'):\n"
    "        if not module.name.startswith(('app.learning', 'app.__main__')):\n"
    "            importlib.import_module(module.name)\n"
    "import pytest, xdist, hypothesis, playwright.sync_api, pyarrow.parquet, dask.distributed\n",
)


def main() -> int:
    environment = {key: value for key, value in os.environ.items()
                   if key != "PYTHONDONTWRITEBYTECODE"}
    processes = [subprocess.Popen([sys.executable, "-c", code], env=environment) for code in GROUPS]
    return max(process.wait() for process in processes)


if __name__ == "__main__":
    sys.exit(main())
