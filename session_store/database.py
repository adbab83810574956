"""sqlite_utils's :class:`Database` (and its ``quote_identifier``), imported without pandas.

sqlite_utils imports pandas when it is installed (it is: the analysis needs it), only to map
``pandas.Timestamp`` values to TEXT columns; the store writes validated models, never pandas
values. That import cost every process that opens a participant (``run-session``, ``serve``,
``doctor``, a rig's session) 0.4 CPU-seconds of its start. A ``None`` in ``sys.modules`` makes an
import raise ImportError (the import system's documented rule), which sqlite_utils takes as "no
pandas". Where pandas is already imported, sqlite_utils gets it as before.
"""

from __future__ import annotations

import sys

if "pandas" in sys.modules or "sqlite_utils" in sys.modules:
    from sqlite_utils import Database
    from sqlite_utils.db import quote_identifier
else:
    sys.modules["pandas"] = None  # type: ignore[assignment]
    try:
        from sqlite_utils import Database
        from sqlite_utils.db import quote_identifier
    finally:
        del sys.modules["pandas"]

__all__ = ["Database", "quote_identifier"]
