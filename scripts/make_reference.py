"""Write seqrank's shipped true-reward reference from finished `--reward true` runs.

    .venv/bin/python scripts/make_reference.py RUNS_DIR... --measured "FOLDER: COMMAND"

Every run directory under the given folders whose config says `reward = true` is read;
runs are grouped by task and agent settings (`seqrank.reference.REFERENCE_KEY`), and each
evaluation step gets the mean and 95% t-interval over the group's seeds. The entries replace
those of the same task and settings in `src/seqrank/true_reward_reference.json`.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from seqrank.reference import REFERENCE_FILE, reference_key
from seqrank.report.stats import interval
from seqrank.rows import read_rows


def true_reward_runs(folders: list[Path]) -> dict[str, list[Path]]:
    groups: dict[str, list[Path]] = defaultdict(list)
    for folder in folders:
        for config_path in sorted(folder.rglob("config.json")):
            config = json.loads(config_path.read_text())
            run = config_path.parent
            if config.get("reward") != "true" or not (run / "summary.json").exists():
                continue
            key = json.dumps({"task": config["task"], "settings": reference_key(config)})
            groups[key].append(run)
    return groups


def entry(key: str, runs: list[Path], measured: str) -> dict[str, Any]:
    returns: dict[int, list[float]] = defaultdict(list)
    for run in runs:
        for row in read_rows(run / "metrics.jsonl"):
            if row["kind"] == "eval":
                returns[row["step"]].append(row["eval_return"])
    curve = []
    for step in sorted(returns):
        if len(returns[step]) == len(runs):  # only steps every seed reached
            mean, low, high = interval(returns[step])
            curve.append({"step": step, "mean": mean, "low": low, "high": high, "seeds": len(runs)})
    return {**json.loads(key), "curve": curve, "measured": measured}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--measured", required=True, help="results folder and command")
    parser.add_argument("--out", type=Path, default=REFERENCE_FILE)
    args = parser.parse_args()
    entries = [entry(k, runs, args.measured) for k, runs in true_reward_runs(args.folders).items()]
    if not entries:
        raise SystemExit(f"no finished --reward true run under {', '.join(map(str, args.folders))}")
    old = json.loads(args.out.read_text())["entries"] if args.out.exists() else []
    new_keys = {(e["task"], json.dumps(e["settings"])) for e in entries}
    kept = [e for e in old if (e["task"], json.dumps(e["settings"])) not in new_keys]
    args.out.write_text(json.dumps({"entries": kept + entries}, indent=1) + "\n")
    for e in entries:
        print(
            f"{e['task']}: {len(e['curve'])} steps, {e['curve'][-1]['seeds']} seeds -> {args.out}"
        )


if __name__ == "__main__":
    main()
