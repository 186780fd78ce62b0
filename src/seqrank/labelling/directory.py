"""A labelling directory: one process at a time, and the settings it was started with.

`take_directory` checks the path and locks it (`seqrank.dirs.DirLock`) before anything is
written in it; a second `seqrank label` on the same directory is refused. The offline
labelling settings are kept in the database at the first run; a rerun with other settings
(a scheme, a number of questions, a segment length...) is refused with one line naming
each difference, since stored sessions can only continue as they began. Asking more
sessions (`--sessions`) continues a directory.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from seqrank.dirs import DirLock, check_folder, missing_folders, remove_made
from seqrank.envs import same_task
from seqrank.labelling.db import DB_NAME, LabelDB
from seqrank.labelling.gold import GoldPairs, check_gold

SETTINGS_KEY = "offline_settings"
# settings a rerun may change (the team too)
CONTINUABLE = ("sessions", "annotators", "overlap", "overlap_until")


def take_directory(directory: Path, what: str = "labelling directory") -> DirLock:
    """Check `directory`, make it if needed and lock it for this process; ValueError when
    it cannot be used (nothing is left behind then)."""
    check_folder(directory, what)
    made = missing_folders(directory)
    directory.mkdir(parents=True, exist_ok=True)
    lock = DirLock(directory, what)
    try:
        lock.acquire()
    except ValueError:
        remove_made(made)
        raise
    return lock


def check_offline_settings(
    directory: Path, settings: dict[str, Any], gold: GoldPairs | None = None
) -> list[str]:
    """ValueError naming each setting that differs from those the directory began with
    (its labels' task and segment length too, and its gold pairs); else the continuable
    ones a rerun changes, as `--name new (was old)`, to be said."""
    if not (directory / DB_NAME).exists():
        return []
    db = LabelDB.in_dir(directory)
    try:
        stored = db.get_meta(SETTINGS_KEY)
        saved = json.loads(stored) if stored is not None else _from_sessions(db)
        differences = [
            f"--{name.replace('_', '-')} {saved[name]} (not {settings.get(name)})"
            for name in sorted(saved)
            if name not in CONTINUABLE and not _same(name, saved[name], settings.get(name))
        ]
        if differences:
            raise ValueError(
                f"labelling directory {directory} was started with {', '.join(differences)}; "
                "rerun with its settings to continue, or choose another --out"
            )
        _check_labelled(db, directory, settings)
        if gold is not None:
            check_gold(db, gold)
    finally:
        db.close()
    return [
        f"--{name.replace('_', '-')} {_shown(settings.get(name))} (was {_shown(saved[name])})"
        for name in CONTINUABLE
        if name in saved and saved[name] != settings.get(name)
    ]


def _check_labelled(db: LabelDB, directory: Path, settings: dict[str, Any]) -> None:
    """ValueError when the database holds labels of another task or segment length (a
    directory `label online` or a former version labelled in keeps no settings)."""
    task, length = (db.get_meta(name) for name in ("task", "segment_length"))
    where = f"labelling directory {directory} holds labels"
    if task is not None and not same_task(json.loads(task), str(settings.get("task"))):
        raise ValueError(
            f"{where} of task {json.loads(task)}, not {settings.get('task')}: choose another --out"
        )
    if length is not None and json.loads(length) != settings.get("segment_length"):
        raise ValueError(
            f"{where} of {json.loads(length)}-step segments, not {settings.get('segment_length')}: "
            f"give --segment-length {json.loads(length)} to continue it, or choose another --out"
        )


def _same(name: str, saved: Any, given: Any) -> bool:
    if name == "task" and isinstance(saved, str) and isinstance(given, str):
        return same_task(saved, given)  # (walker_walk is dmc:walker_walk)
    return bool(saved == given)


def _shown(value: Any) -> str:
    return ",".join(value) if isinstance(value, list) else str(value)


def record_offline_settings(db: LabelDB, settings: dict[str, Any]) -> None:
    db.set_meta(SETTINGS_KEY, json.dumps(settings))


def _from_sessions(db: LabelDB) -> dict[str, Any]:
    """What a directory made before the settings were kept tells of them: its sessions."""
    rows = [row for row in db.sessions() if row["run"] == "offline"]
    if not rows:
        return {}
    return {"scheme": rows[0]["scheme"], "questions": rows[0]["questions"]}
