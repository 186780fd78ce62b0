"""MkDocs hook: each results folder is an evidence page.

`results/NAME/README.md` is served as `evidence/NAME/index.md` and the folder's pictures
and tables beside it, so the README's own relative links work on the site as they do in
the repository; `results/NAME.md` is served as `evidence/NAME.md`. Nothing is copied into
`docs/`: the results stay the one source.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

SERVED = {".md", ".png", ".svg", ".csv"}  # what a results page shows or links to
SKIPPED = {"runs"}  # the runs' own folders: raw logs, not pages


def on_files(files: Files, config: Any) -> Files:
    results = Path(config["config_file_path"]).parent / "results"
    for path in sorted(results.rglob("*")):
        relative = path.relative_to(results)
        if not path.is_file() or path.suffix not in SERVED or SKIPPED & set(relative.parts):
            continue
        if path.name == "README.md":
            target = relative.with_name("index.md")
        else:
            target = relative
        files.append(
            File.generated(config, f"evidence/{target.as_posix()}", abs_src_path=str(path))
        )
    return files
