"""docs/guides/which-scheme.md: every number on the page comes from a committed file.

Each table row of the page is rebuilt here from the results file its table names and must
be a line of the page. Each number in its prose is either a phrase quoted from a file
(`QUOTED`: it must stand in that file and on the page) or a phrase rebuilt from a results
file (`computed_phrases`). Once those are taken out of the page (its code blocks, inline
code and link targets too), no digit may be left but in `NAMES`: so a number changed on
the page, or in its results file, fails here.
"""

from __future__ import annotations

import json
import re
from functools import cache
from pathlib import Path
from typing import Any

from seqrank.theory import exact_sequential_pairs, root_pairs

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs/guides/which-scheme.md"
MECHANISM_WINDOW_OPEN = "results/reward-bench/mechanism/window-open/summary.json"
# each scheme's questions against half as many pairwise ones, as schemes.md pairs them
PER_CLIP_PAIRED = [
    f"| window-open | uniform | {scheme} | {2 * q} | {q} |"
    for scheme in ("sequential", "root")
    for q in (100, 300, 500)
]
SCHEMES = ("pairwise", "sequential", "root", "ranked")

# (file, phrase): the phrase is on the page as the file says it (whitespace aside)
QUOTED = [
    ("results/reward-bench/README.md", "10 seeds"),
    ("results/online-walker-cpu/README.md", "5 seeds"),
    ("results/online-walker-cpu/README.md", "100 questions"),
    ("results/online-walker-cpu/README.md", "60 000 steps"),
    ("results/online-walker-cpu/README.md", "400 questions"),
    ("results/online-walker-cpu/README.md", "1M steps"),
    ("results/online-walker-cpu/README.md", "mean ± std over 5 seeds"),
    ("results/online-walker-cpu/README.md", "holds 0.5"),
    ("results/online-walker-cpu/README.md", "8.5%"),
    ("results/online-walker-cpu/report.md", "95% CI"),
    ("results/reward-bench/walker_walk/README.md", "95% t-interval"),
    ("results/online-walker-mistake/README.md", "95% bootstrap"),
    ("src/seqrank/rewardbench/curves.py", "3 s a question"),
    # the paper's window-open row (supplementary Table 7) and the sweep's state
    ("results/reward-bench/mechanism/README.md", "10 000 steps"),
    ("results/online-window-open-cpu/README.md", "49.4 ± 43.2"),
    ("results/online-window-open-cpu/README.md", "72.4 ± 39.0"),
    ("results/online-window-open-cpu/README.md", "98.6 ± 3.1"),
    ("results/online-window-open-cpu/README.md", "1,000 questions"),
    ("results/online-window-open-cpu/README.md", "150,000 steps"),
    ("results/online-window-open-cpu/README.md", "instead of 1M"),
    ("results/online-window-open-cpu/README.md", "8 seeds each"),
    ("results/online-window-open-cpu/README.md", "ranked and the true-reward agent 4"),
    ("results/online-window-open-cpu/README.md", "50-step segments"),
    # per question and per clip
    ("results/noise-aware/README.md", "sessions of 25"),
    ("results/reward-bench/button-press/README.md", "50 questions every interval overlaps"),
    ("results/reward-bench/button-press/README.md", "50 questions"),
    ("results/reward-learners/README.md", "200 questions"),
    ("results/reward-learners/README.md", "at 25 and 50 questions"),
    ("results/reward-bench/cheetah_run/README.md", "labelled pairs at 200"),
    (
        "results/reward-bench/window-open/README.md",
        "the paper counts 640 for root at its first reward update",
    ),
    ("results/reward-bench/window-open/README.md", "sessions of 100"),
    ("results/reward-bench/window-open/README.md", "best-of-10 regret"),
    ("results/reward-bench/window-open/README.md", "top-10% recall"),
    ("results/reward-bench/window-open/README.md", "for all 10 epochs at every fit"),
    # a teacher who slips
    ("results/online-walker-mistake/README.md", "10% of answers flipped"),
    ("results/online-walker-mistake/README.md", "+86.2 [+10.3, +162.1]"),
    ("results/online-walker-mistake/README.md", "+44.4 [-67.8, +156.6]"),
    ("results/online-walker-mistake/README.md", "-90.6 [-165.5, -15.6]"),
    # smaller online runs
    ("results/sweep-walker-cpu/README.md", "2 seeds"),
    ("results/sweep-walker-cpu/README.md", "30 000 steps"),
    ("results/sweep-walker-cpu/README.md", "60 questions"),
    ("results/sb3/README.md", "P(pairwise > sequential) = 0.88 [0.60, 1.00]"),
    (
        "results/sb3/README.md",
        "A sequential session of 20 questions compares 21 distinct segments, a pairwise one 40",
    ),
]
# numbers that name something (an issue, a table or section of the paper), not a measure
NAMES = ["Issue 46", "issue 46", "10-seed", "Table 2", "Table 6", "Table 7", "D.6", "D.7"]
# the paper's Table 6, as results/online-walker-cpu/README.md quotes it
PAPER_TABLE_6 = {
    "pairwise": "848.1 ± 170.5",
    "sequential": "864.4 ± 120.8",
    "root": "919.8 ± 31.2",
    "true-reward": "957.3 ± 2.3",
}


@cache
def data(path: str) -> Any:
    return json.loads((ROOT / path).read_text())


def flat(text: str) -> str:
    return " ".join(text.split())


def only(entries: list[dict[str, Any]], **where: Any) -> dict[str, Any]:
    (found,) = [e for e in entries if all(e.get(k) == v for k, v in where.items())]
    return found


def ci(value: list[float], digits: int = 3) -> str:
    mean, low, high = value
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def row(*cells: str) -> str:
    """A markdown table row; an empty cell as `| |`."""
    return "|" + "|".join(f" {cell} " if cell else " " for cell in cells) + "|"


def spread(entry: dict[str, Any]) -> str:
    return f"{entry['mean']:.1f} ± {entry['std']:.1f}"


def iqm(entry: dict[str, Any], digits: int = 1) -> str:
    return ci([entry["iqm"], entry["iqm_low"], entry["iqm_high"]], digits)


def per_question() -> list[str]:
    """Reward benchmark, oracle, plain: accuracy at 50 and 200 questions, pairs at 200."""
    rows = []
    for task in ("walker_walk", "cheetah_run", "button-press"):
        summary = data(f"results/reward-bench/{task}/summary.json")
        for scheme in SCHEMES:
            at = {
                q: only(summary, teacher="oracle", learner="plain", scheme=scheme, questions=q)
                for q in (50, 200)
            }
            assert at[50]["seeds"] == at[200]["seeds"] == 10
            accuracy = (ci(at[q]["accuracy"]) for q in (50, 200))
            rows.append(row(task, scheme, *accuracy, f"{at[200]['pairs']:.0f}"))
    return rows


def per_clip() -> list[str]:
    """window-open's pool, 10 seeds, uniform draws: clips, annotator minutes and the
    measures at each budget."""
    summary = data(MECHANISM_WINDOW_OPEN)
    rows = []
    for scheme in ("pairwise", "sequential", "root"):
        for questions in (100, 500, 1000):
            e = only(summary, teacher="oracle", learner="plain", scheme=scheme, questions=questions)
            assert e["seeds"] == 10
            means = (f"{e[key][0]:.3f}" for key in ("top_accuracy", "top_recall", "regret"))
            minutes = f"{e['annotator_seconds'] / 60:.1f}"
            cells = (str(questions), f"{e['clips']:.0f}", minutes, ci(e["accuracy"]), *means)
            rows.append(row(scheme, *cells))
    return rows


def under_mistake() -> list[str]:
    """Reward benchmark, `mistake`, 200 questions: each learner's accuracy."""
    summary = data("results/reward-learners/summary.json")

    def at(scheme: str, learner: str) -> dict[str, Any]:
        found = only(summary, teacher="mistake", questions=200, scheme=scheme, learner=learner)
        assert found["seeds"] == 10
        return found

    def wrong(entry: dict[str, Any]) -> str:
        share = entry["inferred_wrong"]
        return "infers none" if share is None else f"{100 * share[0]:.1f}%"

    rows = []
    for scheme in SCHEMES:
        plain, checked, rime = (at(scheme, x) for x in ("plain", "plain+checked", "rime"))
        same = checked["accuracy"] == plain["accuracy"]
        both = [e for e in summary if e["learner"] == "rime+checked" and e["scheme"] == scheme]
        rime_checked = ci(at(scheme, "rime+checked")["accuracy"]) if both else "not run"
        rows.append(
            row(
                scheme,
                ci(plain["accuracy"]),
                wrong(plain),
                "identical" if same else ci(checked["accuracy"]),
                wrong(checked),
                ci(rime["accuracy"]),
                rime_checked,
            )
        )
    return rows


def online_mistake() -> list[str]:
    table = data("results/online-walker-mistake/report.json")["table"]
    labels = {
        "pairwise, plain": "pairwise",
        "pairwise, RIME": "pairwise+checked+rime",
        "pairwise, RIME with its warm start": "pairwise+rime+warm",
        "root, plain": "root",
        "root, RIME + `checked`": "root+checked+rime",
    }
    rows = []
    for label, method in labels.items():
        e = only(table, task="walker_walk", method=method)
        assert e["n"] == 5 and e["steps"] == 60_000
        rows.append(row(label, spread(e), iqm(e)))
    return rows


def online() -> list[str]:
    report = data("results/online-walker-cpu/report.json")
    quoted = (ROOT / "results/online-walker-cpu/README.md").read_text()
    rows = []
    for method in (*SCHEMES, "true-reward"):
        e = only(report["table"], task="walker_walk", method=method)
        assert e["n"] == 5 and e["steps"] == 60_000
        relative = (
            ""
            if e["relative"] is None
            else ci([e[f"relative{s}"] for s in ("", "_low", "_high")], 2)
        )
        better = [
            p
            for p in report["probability_of_improvement"]
            if (p["x"], p["y"]) == (method, "pairwise")
        ]
        chance = ci([better[0][k] for k in ("p", "low", "high")], 2) if better else ""
        paper = PAPER_TABLE_6.get(method, "not in the paper")
        if method in PAPER_TABLE_6:
            assert f"| {method} | {paper} |" in quoted
        label = method.replace("-", " ")
        rows.append(row(label, spread(e), iqm(e), relative, chance, paper))
    return rows


def paired_per_clip() -> list[str]:
    """The page's per-clip comparisons: whole lines of the grid's schemes.md."""
    lines = (ROOT / "results/reward-bench/mechanism/window-open/schemes.md").read_text()
    found = [line for line in lines.splitlines() if line.startswith(tuple(PER_CLIP_PAIRED))]
    assert len(found) == len(PER_CLIP_PAIRED)
    return found


def computed_phrases() -> list[str]:
    clips = data(MECHANISM_WINDOW_OPEN)

    def window(scheme: str, questions: int) -> dict[str, Any]:
        return only(clips, teacher="oracle", learner="plain", scheme=scheme, questions=questions)

    minutes = {s: f"{window(s, 100)['annotator_seconds'] / 60:.1f}" for s in ("root", "pairwise")}
    sweep = data("results/sweep-walker-cpu/report.json")["table"]
    ppo = data("results/sb3/report.json")["table"]
    finished = len(list((ROOT / "results/online-window-open-cpu/runs").rglob("summary.json")))
    windows = data("results/reward-bench/mechanism/walker-windows/summary.json")

    def at_100(scheme: str, learner: str = "plain") -> dict[str, Any]:
        return only(windows, scheme=scheme, learner=learner, questions=100)

    return [
        f"{finished} of 32 runs",
        "at 100 questions held-out accuracy is "
        + ", ".join(f"{s} {at_100(s)['accuracy'][0]:.3f}" for s in ("pairwise", "sequential"))
        + f", root {at_100('root')['accuracy'][0]:.3f} (uniform draws)",
        f"root labels {at_100('root', 'plain+collection')['pairs']:.0f} pairs against "
        f"{at_100('root')['pairs']:.0f}",
        f"reaches {at_100('root', 'plain+collection')['accuracy'][0]:.3f}, no more accurate",
        f"100 root questions cost {minutes['root']} annotator minutes against "
        f"{minutes['pairwise']} for pairwise",
        f"a session of 100 questions shows {window('root', 100)['clips']:.0f} clips",
        # seqrank theory's expectation for a session of M = 101 segments
        "session of 100 questions (101 segments",
        f"expects {root_pairs(101) - 100:.1f} inferred pairs for root and "
        f"{exact_sequential_pairs(101) - 100:.1f} for sequential",
        ", ".join(
            f"{s} {spread(only(sweep, method=s))}" for s in ("root", "pairwise", "sequential")
        ),
        ", ".join(
            f"{s} {spread(only(ppo, task='gym:Pendulum-v1', method=f'{s}/sb3-ppo'))}"
            for s in ("pairwise", "sequential")
        ),
    ]


def table_rows() -> list[str]:
    tables = [*per_question(), *per_clip(), *paired_per_clip(), *under_mistake()]
    return [*tables, *online_mistake(), *online()]


def test_every_table_row_is_rebuilt_from_its_results_file():
    lines = set(PAGE.read_text().splitlines())
    missing = [line for line in table_rows() if line not in lines]
    assert not missing, "rows the results files give, not on the page:\n" + "\n".join(missing)


def test_every_quoted_phrase_stands_in_its_file_and_on_the_page():
    page = flat(PAGE.read_text())
    for path, phrase in QUOTED:
        assert phrase in flat((ROOT / path).read_text()), f"{path} no longer says {phrase!r}"
        assert phrase in page, f"the page no longer says {phrase!r}"
    for phrase in computed_phrases():
        assert phrase in page, f"the results give {phrase!r}, not on the page"


def test_no_number_on_the_page_is_left_unchecked():
    text = PAGE.read_text()
    text = re.sub(r"```.*?```", " ", text, flags=re.S)  # commands, checked by test_docs
    rows = set(table_rows())
    text = "\n".join(line for line in text.splitlines() if line not in rows)
    text = re.sub(r"\]\([^)]*\)", "]", re.sub(r"`[^`]*`", " ", text))  # code, link targets
    text = flat(text)
    phrases = [p for _, p in QUOTED] + computed_phrases() + NAMES
    for phrase in sorted(phrases, key=len, reverse=True):
        text = text.replace(phrase, " ")
    left = re.findall(r"(?<![A-Za-z_])\d[\d.,]*", text)
    assert not left, f"numbers on the page that no results file checks: {left}"
