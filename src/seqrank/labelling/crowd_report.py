"""The operator page of a team, and what it shows: per annotator their answers, pace,
time-outs, latency, hand-overs, agreement on overlaps (Cohen's kappa) and reliability; the
session's chains; the run's evaluation curve. All of it read from the labelling database,
so the page shows what is stored, whatever the training process is doing."""

from __future__ import annotations

from collections import Counter, defaultdict
from statistics import median
from typing import Any

import numpy as np
from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import HTMLResponse

from seqrank.feedback.peer_reliability import GOLD, estimate_from_peers
from seqrank.feedback.reliability import Reliability, evidence_rows
from seqrank.labelling.access import OPERATOR
from seqrank.labelling.crowd_keys import GOLD_CHECKS
from seqrank.labelling.human import Hub
from seqrank.labelling.server import STATIC

BREAK_S = 120.0  # a gap between two answers longer than this is a break, not answering


def operator_routes(hub: Hub) -> APIRouter:
    """A team's operator page, for the main token only (annotators' tokens cannot)."""
    router = APIRouter()

    def operator_only(request: Request) -> None:
        if request.state.who != OPERATOR:
            raise HTTPException(403, "the operator page needs the operator's token")

    @router.get("/operator", response_class=HTMLResponse)
    def operator_page(request: Request) -> str:
        operator_only(request)
        return (STATIC / "operator.html").read_text()

    @router.get("/api/operator")
    def operator_state(request: Request) -> dict[str, object]:
        operator_only(request)
        return operator_view(hub, str(request.base_url))

    return router


def operator_view(hub: Hub, base: str) -> dict[str, Any]:
    """The operator page's data; `base`: the server's address, for the team's links."""
    team, view = hub.crowd, hub.state.now()
    rows = team.tables.answer_rows()
    gold = _gold_known(rows, team.gold)
    reliability = _reliability(rows, gold)
    kappas = _kappas([r for r in rows if r["chain"] != GOLD_CHECKS])
    handed = team.tables.withdrawn_count()
    people = []
    for name, token in team.tokens.items():
        mine = [r for r in rows if r["annotator"] == name]
        people.append(
            {
                "name": name,
                "address": f"{base}?token={token}",
                **_pace(mine),
                "handed_over": handed.get(name, 0),
                "kappa": kappas.get(name),
                **_reliability_fields(reliability.get(name)),
                **_gold_fields(mine, gold),
            }
        )
    return {
        "phase": view.phase,
        "message": view.message,
        "run": view.run,
        "scheme": view.scheme,
        "sessions": view.sessions_total,
        "annotators": people,
        "chains": _chains(hub, rows),
        "curve": [{"step": step, "eval_return": value} for step, value in view.curve],
        "overlap": team.overlap,
        "overlap_until": team.overlap_until,
        "reassign_after_s": team.reassign_after,
    }


def _pace(rows: list[Any]) -> dict[str, Any]:
    """Answers, answers per minute (over the time between their answers, a break left
    out), time-outs and the median latency."""
    return {
        "answers": len(rows),
        "per_minute": answers_per_minute([r["answered_at"] for r in rows]),
        "timeouts": sum(r["choice"] == "timeout" for r in rows),
        "median_latency_ms": median(r["latency_ms"] for r in rows) if rows else None,
    }


def answers_per_minute(times: list[float]) -> float | None:
    """Answers a minute while answering: over the gaps between consecutive answers, each
    longer than `BREAK_S` left out (the page stopped, the agent training between sessions,
    a person away); None before two answers close enough to time."""
    gaps = np.diff(np.sort(np.asarray(times, dtype=float)))
    kept = gaps[gaps <= BREAK_S]
    return len(kept) / (kept.sum() / 60.0) if kept.sum() > 0 else None


def _reliability(
    rows: list[Any], gold: dict[tuple[int, int], str] | None = None
) -> dict[str, Reliability]:
    """Every annotator's reliability from the stored answers: the estimator whose flags
    reward training acts on (`--crowd-weighting drop`), from the other people's answers
    and the known order of the gold pairs answered (`gold`: pair -> "first"/"second")."""
    evidence = [(r["first"], r["second"], r["answer"], r["annotator"], None) for r in rows]
    evidence += [(a, b, said, GOLD, None) for (a, b), said in (gold or {}).items()]
    return estimate_from_peers(evidence_rows(evidence))


def _gold_known(
    rows: list[Any], gold: tuple[tuple[int, int, bool], ...]
) -> dict[tuple[int, int], str]:
    """The known answer ("first" or "second") of each gold pair somebody answered."""
    known = {(a, b): "first" if first else "second" for a, b, first in gold}
    asked = {(r["first"], r["second"]) for r in rows if r["chain"] == GOLD_CHECKS}
    return {pair: said for pair, said in known.items() if pair in asked}


def _gold_fields(mine: list[Any], gold: dict[tuple[int, int], str]) -> dict[str, Any]:
    """How many gold questions the annotator answered, and how many of them right."""
    answered = [
        r for r in mine if r["chain"] == GOLD_CHECKS and r["answer"] in ("first", "second")
    ]  # (a skip or a time-out is no answer to be right or wrong in)
    right = sum(gold.get((r["first"], r["second"])) == r["answer"] for r in answered)
    return {"gold_answered": len(answered), "gold_right": right}


def _reliability_fields(found: Reliability | None) -> dict[str, Any]:
    if found is None:
        return {"reliability": None, "low": None, "high": None, "flagged": False}
    return {
        "reliability": found.estimate,
        "low": found.low,
        "high": found.high,
        "rests_on": found.answers,
        "flagged": found.flagged,
        "flag_below": found.flag_below,
        "flag_after": found.flag_after,
    }


def _kappas(rows: list[Any]) -> dict[str, float | None]:
    """Each annotator's Cohen's kappa against the other answers to the pairs they
    overlapped on (first / second / equal; skips left out)."""
    by_pair: dict[tuple[int, int], list[tuple[str, str]]] = defaultdict(list)
    for r in rows:
        if r["answer"] in ("first", "second", "equal"):
            pair = (min(r["first"], r["second"]), max(r["first"], r["second"]))
            said = r["answer"]
            if r["first"] > r["second"] and said != "equal":
                said = "second" if said == "first" else "first"
            by_pair[pair].append((r["annotator"], said))
    pairs: dict[str, list[tuple[str, str]]] = defaultdict(list)
    for answers in by_pair.values():
        for who, said in answers:
            pairs[who] += [(said, other) for person, other in answers if person != who]
    return {who: cohen_kappa(found) for who, found in pairs.items()}


def cohen_kappa(pairs: list[tuple[str, str]]) -> float | None:
    """Cohen's kappa of paired labels; None for fewer than two pairs or when chance
    agreement is certain (every label the same)."""
    if len(pairs) < 2:
        return None
    observed = sum(a == b for a, b in pairs) / len(pairs)
    left, right = Counter(a for a, _ in pairs), Counter(b for _, b in pairs)
    n = len(pairs)
    chance = sum(left[k] * right[k] for k in left) / (n * n)
    return None if chance >= 1.0 else (observed - chance) / (1.0 - chance)


def _chains(hub: Hub, rows: list[Any]) -> list[dict[str, Any]]:
    """The current session's chains: owner, answered of their questions (`rows`: every
    answered crowd question)."""
    sessions = hub.db.sessions()
    if not sessions:
        return []
    latest = sessions[-1]
    run, session = latest["run"], latest["session"]
    answered = Counter(r["chain"] for r in rows if r["run"] == run and r["session"] == session)
    return [
        {
            "session": session + 1,
            "chain": c.chain,
            "owner": c.owner,
            "answered": answered.get(c.chain, 0),
            "questions": c.budget,
            "continues": c.parent,
        }
        for c in hub.crowd.tables.chains(run, session)
    ]
