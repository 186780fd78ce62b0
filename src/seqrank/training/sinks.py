"""Where a run's metric rows go besides `metrics.jsonl`: TensorBoard event files in the run
directory (always) and Weights & Biases (`--wandb PROJECT`).

Both get the same numbers under grouped names (`TAGS`), plotted against the environment
step: `eval/return`, `losses/critic`, `feedback/pairs_per_question`,
`reward/heldout_accuracy`, ... A `metrics.jsonl` row of kind K maps key k to `tag(K, k)`;
text and missing values are left out.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import Any, Protocol

# (kind, key) -> name; keys not listed go to `<kind group>/<key>`
TAGS: dict[tuple[str, str], str] = {
    ("eval", "eval_return"): "eval/return",
    ("eval", "eval_return_std"): "eval/return_std",
    ("eval", "eval_success_rate"): "eval/success_rate",
    ("eval", "alpha"): "train/alpha",
    ("eval", "total_asked"): "feedback/total_asked",
    ("eval", "total_inferred"): "feedback/total_inferred",
    ("eval", "steps_per_second"): "perf/steps_per_second",
    ("eval", "wall_seconds"): "perf/wall_seconds",
    ("train", "critic_loss"): "losses/critic",
    ("train", "actor_loss"): "losses/actor",
    ("train", "alpha"): "train/alpha",
    ("train", "intrinsic_reward_std"): "pretrain/intrinsic_reward_std",
    ("train", "meta_outer_loss"): "losses/meta_outer",
    ("feedback", "reward_loss"): "reward/loss",
    ("feedback", "reward_train_accuracy"): "reward/train_accuracy",
    ("feedback", "reward_heldout_accuracy"): "reward/heldout_accuracy",
    ("feedback", "reward_correlation"): "reward/correlation",
    ("feedback", "reward_epochs"): "reward/epochs",
}
GROUPS = {"eval": "eval", "train": "train", "feedback": "feedback"}


def tag(kind: str, key: str) -> str:
    return TAGS.get((kind, key), f"{GROUPS.get(kind, kind)}/{key}")


def scalars(row: dict[str, Any]) -> dict[str, float]:
    """A row's numbers under their names (step and kind are the axis, not values)."""
    kind = str(row.get("kind", "other"))
    return {
        tag(kind, key): float(value)
        for key, value in row.items()
        if key not in ("step", "kind")
        and isinstance(value, int | float)
        and not isinstance(value, bool)
    }


class MetricSink(Protocol):
    def write(self, row: dict[str, Any]) -> None: ...

    def close(self) -> None: ...


class TensorBoardSink:
    """Event files in the run directory: `tensorboard --logdir seqrank-out/runs` shows every
    run by its folder. A resumed run purges the events after its checkpoint's step."""

    def __init__(self, directory: Path, purge_step: int | None):
        from torch.utils.tensorboard import SummaryWriter

        self.writer = SummaryWriter(log_dir=str(directory), purge_step=purge_step)

    def write(self, row: dict[str, Any]) -> None:
        for name, value in scalars(row).items():
            self.writer.add_scalar(name, value, global_step=int(row["step"]))
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


class WandbSink:
    """One W&B run per run directory; a resumed run continues it (its id is kept in
    `wandb.json`). `WANDB_MODE=offline` keeps everything on disk."""

    def __init__(self, project: str, directory: Path, config: dict[str, Any]):
        try:
            import wandb
        except ImportError:
            raise ValueError(
                "--wandb needs Weights & Biases: pip install 'seqrank[wandb]'"
            ) from None
        saved = directory / "wandb.json"
        run_id = json.loads(saved.read_text())["id"] if saved.exists() else uuid.uuid4().hex[:12]
        saved.write_text(json.dumps({"project": project, "id": run_id}) + "\n")
        self.run = wandb.init(
            project=project,
            id=run_id,
            resume="allow",
            dir=str(directory),
            name=directory.name,
            config=config,
            reinit="create_new",
        )
        # evaluations of the fast path arrive after later steps: plot against the env step
        self.run.define_metric("env_step")
        self.run.define_metric("*", step_metric="env_step")

    def write(self, row: dict[str, Any]) -> None:
        self.run.log({"env_step": int(row["step"]), **scalars(row)})

    def close(self) -> None:
        self.run.finish()
