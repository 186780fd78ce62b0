"""JSON-lines files written a row at a time (run metrics, benchmark rows)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Every complete row; a last line cut by a kill ends the reading (the rows before it
    are good). A missing file has no rows."""
    if not path.exists():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            break
    return rows
