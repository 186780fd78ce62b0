"""MkDocs hook: each results folder is an evidence page.

`results/NAME/...` is served as `evidence/NAME/...` (a README.md as the folder's page,
its pictures and tables beside it), so the READMEs' relative links work on the site as
they do in the repository. Nothing is copied into `docs/`: the results stay the one
source.
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
        uri = f"evidence/{relative.as_posix()}"
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    """A results README's page ends with the folder's plots it does not show itself."""
    uri = page.file.src_uri
    if not uri.startswith("evidence/") or not uri.endswith("README.md"):
        return markdown
    folder = (
        Path(config["config_file_path"]).parent
        / "results"
        / Path(uri).parent.relative_to("evidence")
    )
    plots = [p.name for p in sorted(folder.glob("*.png")) if f"]({p.name})" not in markdown]
    if not plots:
        return markdown
    shown = "\n\n".join(f"![{name}]({name})" for name in plots)
    return f"{markdown.rstrip()}\n\n## Plots\n\n{shown}\n"
