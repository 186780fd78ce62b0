"""The rows a run writes to metrics.jsonl and summary.json (their fields are documented in
docs/reference/metrics.md), built from the counters and what each phase returns."""

from __future__ import annotations

from typing import Any

from seqrank.config import TrainConfig
from seqrank.feedback.closure import AugmentationStats
from seqrank.feedback.crowd_record import CrowdRecord
from seqrank.feedback.reliability import Reliability
from seqrank.reward.model import RewardTrainResult
from seqrank.training.eval_worker import score_row
from seqrank.training.evaluation import PolicyScore
from seqrank.training.runtime import Runtime
from seqrank.training.state import Counters

TRAIN_LOG_EVERY = 1_000  # steps between `train` rows
QUERY_WINDOW = ("query_first_episode", "query_last_episode")


def count_session(c: Counters, stats: AugmentationStats) -> None:
    c.sessions += 1
    c.asked += stats.asked
    c.answered += stats.answered
    c.inferred += stats.inferred
    c.inferred_wrong += stats.inferred_wrong or 0
    c.last_session_step = c.step


def feedback_row(
    c: Counters,
    stats: AugmentationStats,
    result: RewardTrainResult | None,
    total_pairs: int,
    quality: dict[str, float],
    episodes: tuple[int, int] | None = None,
) -> dict[str, Any]:
    """`episodes`: with `query_episodes`, the first and last episode (numbered over the
    run) that the session's candidate segments were cut from."""
    window = {} if episodes is None else dict(zip(QUERY_WINDOW, episodes, strict=True))
    return {
        "step": c.step,
        "kind": "feedback",
        "session": c.sessions,
        "questions": stats.asked,
        "answered": stats.answered,
        "equal": stats.equal,
        "skipped": stats.skipped,
        "inferred": stats.inferred,
        "inferred_wrong": stats.inferred_wrong,
        "asked_wrong": stats.asked_wrong,
        "pairs_per_question": stats.pairs_per_question,
        "max_degree": stats.max_degree,
        "mean_degree": stats.mean_degree,
        "cyclic_components": stats.cyclic_components,
        "total_asked": c.asked,
        "total_inferred": c.inferred,
        "total_inferred_wrong": c.inferred_wrong,
        "total_pairs": total_pairs,
        "reward_epochs": result.epochs if result else 0,
        "reward_loss": result.loss if result else None,
        "reward_train_accuracy": result.accuracy if result else None,
        **(result.learner if result else {}),  # SURF's pseudo-labels, RIME's selection
        **quality,
        **window,
    }


def crowd_fields(crowd: CrowdRecord, reliability: dict[str, Reliability]) -> dict[str, Any]:
    """A crowd's session: its length with its people side by side, their time added up,
    the second opinions (`reasks`: those asking a flagged member's question again), and
    each annotator's reliability so far (`crowd/NAME/...`)."""
    fields: dict[str, Any] = {
        "crowd_seconds": crowd.seconds,
        "crowd_person_seconds": crowd.person_seconds,
        "second_opinions": len(crowd.second_opinions),
        "reasks": sum(o.reask for o in crowd.second_opinions),
    }
    for name, r in reliability.items():
        fields.update({
            f"crowd/{name}/reliability": r.estimate,
            f"crowd/{name}/low": r.low,
            f"crowd/{name}/high": r.high,
            f"crowd/{name}/answers": r.answers,
            f"crowd/{name}/agreement": r.agreement,
            f"crowd/{name}/flagged": r.flagged,
        })  # fmt: skip
    return fields


def train_row(
    c: Counters, phase: str, agent_metrics: dict[str, float], entropy_std: float
) -> dict[str, Any]:
    row: dict[str, Any] = {"step": c.step, "kind": "train", "phase": phase, **agent_metrics}
    if phase == "pretrain":
        row["intrinsic_reward_std"] = entropy_std
    return {**row, **c.extra}


def eval_context(c: Counters, agent_metrics: dict[str, float]) -> dict[str, Any]:
    """What an evaluation row holds besides the scores, taken when it is submitted."""
    return {
        "total_asked": c.asked,
        "total_inferred": c.inferred,
        **agent_metrics,
        "steps_per_second": c.steps_per_second,
        "wall_seconds": c.train_seconds,
    }


def eval_row(c: Counters, step: int, score: PolicyScore, context: dict[str, Any]) -> dict[str, Any]:
    row = score_row(score)
    c.last_eval_return, c.last_eval_success = row["eval_return"], row["eval_success_rate"]
    return {"step": step, "kind": "eval", **row, **context}


def live(c: Counters) -> dict[str, Any]:
    """What the progress display shows."""
    return {
        "eval_return": c.last_eval_return,
        "asked": c.asked,
        "inferred": c.inferred,
        "sessions": c.sessions,
        "sps": c.steps_per_second,
    }


def summary(
    config: TrainConfig, c: Counters, rows: list[dict[str, Any]], runtime: Runtime
) -> dict[str, Any]:
    """The finished run's numbers, and the update path and precision of the process that
    finished it (`--path auto` is resolved again on a machine that resumes a run)."""
    evals = [r for r in rows if r["kind"] == "eval"]
    asks = config.reward.asks  # a baseline asks nothing: no scheme or teacher to name
    return {
        "task": config.task,
        "scheme": config.scheme if asks else None,
        "teacher": config.teacher if asks else None,
        "backbone": config.backbone,
        "reward": config.reward,
        "steps": c.step,
        "final_eval_return": c.last_eval_return,
        "final_eval_success_rate": c.last_eval_success,
        "best_eval_return": max((r["eval_return"] for r in evals), default=None),
        "sessions": c.sessions,
        "asked": c.asked,
        "answered": c.answered,
        "inferred": c.inferred,
        "inferred_wrong": c.inferred_wrong,
        "wall_seconds": c.train_seconds,
        "steps_per_second": c.steps_per_second,
        "update_path": runtime.path,
        "precision": runtime.precision,
        "eval_curve": [(r["step"], r["eval_return"]) for r in evals],
    }
