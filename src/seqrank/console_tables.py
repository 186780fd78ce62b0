"""Terminal tables for `seqrank theory` and `seqrank simulate`, and the progress bar (rich)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from seqrank.simulate import CellResult
from seqrank.theory import PAPER_FIGURE13, TheoryRow


def progress_bar(console: Console) -> Progress:
    """A transient bar: description, bar, done/total, elapsed time."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )


def _num(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _pm(mean: float, se: float, digits: int = 2) -> str:
    return f"{mean:.{digits}f} ± {se:.{digits}f}"


def _table(title: str, headers: Sequence[str]) -> Table:
    table = Table(title=title, title_justify="left")
    for header in headers:
        table.add_column(header, justify="right")
    return table


def print_theory(
    out: Console, rows: Sequence[TheoryRow], findings: Sequence[str], args: argparse.Namespace
) -> None:
    out.print(_sequential_table(rows, args.sessions))
    out.print(
        "paper a_M: Lemma 1 recurrence; paper linear: 1.392(M-1.324) (Theorem 1); exact: "
        "sum_{d=1}^{M-1} (M-d) 2/(d+1)! -> 2(e-2)M - 2 = 1.4366(M - 1.3922)\n"
    )
    out.print(_root_table(rows, args.sessions))
    out.print("paper b_M: 2(M - H_M) (Theorem 2)\n")
    out.print(_degree_table(rows, args.delta))
    fig = PAPER_FIGURE13
    seq_fig, root_fig = fig["sequential"], fig["root"]
    out.print(
        f"Paper, Figure 13 (M={fig['M']}, measured during training on quadruped_walk): "
        f"sequential augmented {seq_fig['augmented']}, max degree {seq_fig['max_degree']} "  # type: ignore[index]
        f"(bound {seq_fig['degree_bound']}); root augmented {root_fig['augmented']}, "  # type: ignore[index]
        f"max degree {root_fig['max_degree']} (bound {root_fig['degree_bound']}).\n"  # type: ignore[index]
    )
    if findings:
        out.print(f"[bold]Disagreements ({len(findings)}):[/bold]")
        for line in findings:
            out.print(f"  - {line}", highlight=False)
    else:
        out.print("Every formula agrees with enumeration and simulation.")


def _sequential_table(rows: Sequence[TheoryRow], sessions: int) -> Table:
    table = _table(
        "Sequential: expected labelled pairs of a session on M segments (M-1 questions, "
        "perfect teacher)",
        (
            "M",
            "paper a_M",
            "paper linear",
            "exact",
            "enumerated",
            f"simulated (n={sessions})",
            "augmented",
            "paper augm.",
        ),
    )
    for r in rows:
        table.add_row(
            str(r.m),
            _num(r.sequential_paper_recurrence),
            _num(r.sequential_paper_linear),
            _num(r.sequential_exact),
            _num(r.sequential_enumerated),
            _pm(r.sequential_simulated, r.sequential_simulated_se, 3),
            _num(r.sequential_augmented_exact),
            _num(r.sequential_augmented_paper),
        )
    return table


def _root_table(rows: Sequence[TheoryRow], sessions: int) -> Table:
    table = _table(
        "Root: expected labelled pairs",
        ("M", "paper b_M", "enumerated", f"simulated (n={sessions})", "augmented"),
    )
    for r in rows:
        table.add_row(
            str(r.m),
            _num(r.root_paper),
            _num(r.root_enumerated),
            _pm(r.root_simulated, r.root_simulated_se, 3),
            _num(r.root_augmented),
        )
    return table


def _degree_table(rows: Sequence[TheoryRow], delta: float) -> Table:
    table = _table(
        "Dependency graph of labelled pairs (pairs sharing a segment are dependent): "
        f"expected max and mean degree; bounds hold with probability {1 - delta:g}",
        (
            "M",
            "seq max (enum)",
            "seq max (sim)",
            "seq mean",
            "Lemma 3 bound",
            "root max (enum)",
            "root max (sim)",
            "root mean",
            "Lemma 4 bound",
        ),
    )
    for r in rows:
        table.add_row(
            str(r.m),
            _num(r.sequential_max_degree_enumerated, 2),
            _num(r.sequential_max_degree_simulated, 2),
            _num(r.sequential_mean_degree_simulated, 2),
            _num(r.sequential_degree_bound, 2),
            _num(r.root_max_degree_enumerated, 2),
            _num(r.root_max_degree_simulated, 2),
            _num(r.root_mean_degree_simulated, 2),
            _num(r.root_degree_bound, 2),
        )
    return table


def print_simulation(out: Console, results: Sequence[CellResult]) -> None:
    first = results[0]
    table = Table(
        title=f"Feedback efficiency: {first.questions} questions per session, "
        f"{first.sessions} sessions per cell (mean ± standard error)"
    )
    for header in (
        "scheme",
        "teacher",
        "augment",
        "pairs / question",
        "inferred / question",
        "inferred error",
        "asked error",
        "max degree",
        "mean degree",
        "segments",
        "skipped",
        "equal",
        "cycles",
    ):
        left = header in ("scheme", "teacher", "augment")
        # a teacher's name with knobs folds onto more lines rather than being cut: two
        # teachers that differ in a knob's value must stay apart on a narrow terminal
        if header == "teacher":
            table.add_column(header, justify="left", overflow="fold")
        else:
            table.add_column(header, justify="left" if left else "right")
    for r in results:
        table.add_row(
            r.scheme,
            r.teacher,
            r.augment,
            _pm(r.pairs_per_question, r.pairs_per_question_se, 3),
            _num(r.inferred_per_question, 3),
            _percent(r.inferred_error_rate),
            _percent(r.asked_error_rate),
            _pm(r.max_degree, r.max_degree_se, 1),
            _num(r.mean_degree, 1),
            _num(r.unique_segments, 1),
            _num(r.skipped_per_session, 1),
            _num(r.equal_per_session, 1),
            _num(r.cyclic_components_per_session, 2),
        )
    out.print(table)
    print_crowd_members(out, results)


def print_crowd_members(out: Console, results: Sequence[CellResult]) -> None:
    """Each crowd member's estimated reliability beside their true error rate."""
    crowds = [r for r in results if r.members]
    if not crowds:
        return
    table = Table(title="Crowd members: estimated reliability (95% interval) against truth")
    for header in ("scheme", "teacher", "augment", "member", "reliability", "interval",
                   "answers", "agreement", "true error", "flagged"):  # fmt: skip
        table.add_column(header, justify="left" if header in ("scheme", "member") else "right")
    for r in crowds:
        for m in r.members:
            table.add_row(
                r.scheme, r.teacher, r.augment, str(m["name"]),
                _num(m.get("estimate"), 3),  # type: ignore[arg-type]
                f"[{_num(m.get('low'), 3)}, {_num(m.get('high'), 3)}]",  # type: ignore[arg-type]
                str(m.get("answers", 0)),
                _percent(m.get("agreement")),  # type: ignore[arg-type]
                _percent(m.get("true_error_rate")),  # type: ignore[arg-type]
                "yes" if m.get("flagged") else "",
            )  # fmt: skip
    out.print(table)


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f}%"
