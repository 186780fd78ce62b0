#!/usr/bin/env python3
"""Break the core on purpose, one line at a time, and check that the tests notice.

Each entry below is a one-line change that a slip of the hand could make in the core
(closure, schemes, teachers, reward model, SAC, relabelling, critic reset, statistics),
with the tests that must then fail. The script applies each to a copy of `src/` and runs
those tests against the copy; an entry the tests let pass is a hole in the suite.

    .venv/bin/python scripts/break_core.py              # every entry (about 5 minutes)
    .venv/bin/python scripts/break_core.py --only sac   # entries whose name contains "sac"
    .venv/bin/python scripts/break_core.py --list

When you change the core, add the breaks your change could suffer here, and run them:
`tests/test_break_core.py` keeps every entry applicable to today's source.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Break:
    name: str
    file: str  # relative to src/seqrank
    old: str  # must occur exactly once in the file
    new: str
    tests: tuple[str, ...]


BREAKS = (
    Break(
        "loop: the first session's critic reset skipped",
        "training/feedback_phase.py",
        "    if request.session == 0:\n        reset_critic()",
        "    if False:\n        reset_critic()",
        ("tests/training/test_session_effects.py",),
    ),
    Break(
        "reward: the stop rule counts the inferred pairs when asked for the asked ones",
        "feedback/labels.py",
        "[not i for i, k in zip(self.inferred, kept, strict=True) if k]",
        "[i for i, k in zip(self.inferred, kept, strict=True) if k]",
        ("tests/training/test_reward_stop_on.py", "tests/feedback/test_asked_mask.py"),
    ),
    Break(
        "reward: the stop rule's pair marks inverted",
        "reward/model.py",
        "counted = counted[stop_pairs.to(counted.device)]",
        "counted = counted[~stop_pairs.to(counted.device)]",
        ("tests/reward/test_stop_rule.py",),
    ),
    Break(
        "sac: a CPU step's sampled action is the mean",
        "agents/sac/agent.py",
        "return mean if deterministic else drawn",
        "return mean",
        ("tests/agents/test_one_row.py",),
    ),
    Break(
        "acting: one row's log-std left unsquashed",
        "agents/sac/networks.py",
        "(LOG_STD_MAX - LOG_STD_MIN) * (np.tanh(raw_log_std) + 1)",
        "(LOG_STD_MAX - LOG_STD_MIN) * (raw_log_std + 1)",
        ("tests/agents/test_one_row.py",),
    ),
    Break(
        "reward: one row's hidden layers without their leak",
        "reward/model.py",
        "np.maximum(x, LEAKY_SLOPE * x)",
        "np.maximum(x, 0.0 * x)",
        ("tests/agents/test_one_row.py",),
    ),
    Break(
        "loop: no relabelling after a session",
        "training/feedback_phase.py",
        "c.asked)\n    reward.relabel()\n",
        "c.asked)\n",
        ("tests/training/test_session_effects.py",),
    ),
    Break(
        "sac: the entropy term dropped from the target value",
        "agents/sac/agent.py",
        "soft_value = torch.min(q1, q2) - self.alpha * next_log_prob",
        "soft_value = torch.min(q1, q2)",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac: the target value not discounted",
        "agents/sac/agent.py",
        "return self.settings.discount * batch.not_done * soft_value",
        "return batch.not_done * soft_value",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac: terminal transitions bootstrapped",
        "agents/sac/agent.py",
        "return self.settings.discount * batch.not_done * soft_value",
        "return self.settings.discount * soft_value",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac: the temperature steps the wrong way",
        "agents/sac/agent.py",
        "(-log_prob.detach() - self.target_entropy)",
        "(log_prob.detach() - self.target_entropy)",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac: the reset target critic not synced to the new critic",
        "agents/sac/agent.py",
        "self.critic_target.reinitialise()\n        self.critic_target.load_state_dict(",
        "self.critic_target.reinitialise()\n        dict(",
        ("tests/agents/test_sac_paths.py",),
    ),
    Break(
        "sac flat: the entropy term dropped from the target value",
        "agents/sac/flat_update.py",
        "soft_value = torch.minimum(target_q[0], target_q[1]) - alpha * next_log_prob",
        "soft_value = torch.minimum(target_q[0], target_q[1])",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: the target value not discounted",
        "agents/sac/flat_update.py",
        "target = batch.reward + self.agent.discount * batch.not_done * soft_value",
        "target = batch.reward + batch.not_done * soft_value",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: terminal transitions bootstrapped",
        "agents/sac/flat_update.py",
        "target = batch.reward + self.agent.discount * batch.not_done * soft_value",
        "target = batch.reward + self.agent.discount * soft_value",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: the temperature steps the wrong way",
        "agents/sac/flat_update.py",
        "entropy_gap = -log_prob - self.agent.target_entropy",
        "entropy_gap = log_prob - self.agent.target_entropy",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: a sign in the written backward (the log-std's own term of log pi)",
        "agents/sac/flat_backward.py",
        "grad_log_std = grad_pre * std * noise - grad_log_prob",
        "grad_log_std = grad_pre * std * noise + grad_log_prob",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: Adam without its bias correction (the step count starts high)",
        "agents/sac/flat_buffers.py",
        "self.steps.zero_()",
        "self.steps.fill_(10_000)",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "sac flat: the target critic pulled the wrong way (the critic follows its target)",
        "agents/sac/flat_update.py",
        "self.critics.master[size:].lerp_(self.critics.master[:size], tau)",
        "self.critics.master[:size].lerp_(self.critics.master[size:], tau)",
        ("tests/agents/test_sac_by_hand.py",),
    ),
    Break(
        "reward model: equal labels counted as hard in the training accuracy",
        "reward/model.py",
        "hard = y != 0.5",
        "hard = y == y",
        ("tests/reward/test_training_accuracy.py",),
    ),
    Break(
        "reward model: Bradley-Terry logits the wrong way round",
        "reward/model.py",
        "logits = model.segment_returns(segments[first]) - model.segment_returns(segments[second])",
        "logits = model.segment_returns(segments[second]) - model.segment_returns(segments[first])",
        ("tests/reward/test_learners.py", "tests/reward/test_training_accuracy.py"),
    ),
    Break(
        "schemes: root keeps the loser",
        "feedback/schemes.py",
        "first_is_defender=True) is Answer.SECOND:",
        "first_is_defender=True) is Answer.FIRST:",
        ("tests/feedback/test_schemes.py",),
    ),
    Break(
        "schemes: sequential keeps its first segment as the defender",
        "feedback/schemes.py",
        "        defender = challenger\n",
        "        pass\n",
        ("tests/feedback/test_schemes.py",),
    ),
    Break(
        "teachers: the mistake never flips",
        "feedback/teachers.py",
        "answer = answer.flipped()",
        "answer = answer",
        ("tests/feedback/test_teachers.py",),
    ),
    Break(
        "teachers: myopia weights the first step most",
        "feedback/teachers.py",
        "weights = gamma ** np.arange(horizon - 1, -1, -1, dtype=np.float64)",
        "weights = gamma ** np.arange(horizon, dtype=np.float64)",
        ("tests/feedback/test_teachers.py",),
    ),
    Break(
        "closure: a majority vote read the wrong way round",
        "feedback/closure.py",
        "edge = (a, b) if mean > 0.5 else (b, a)",
        "edge = (b, a) if mean > 0.5 else (a, b)",
        ("tests/feedback/test_closure.py",),
    ),
    Break(
        "statistics: the bootstrap interval at 90%, not 95%",
        "report/stats.py",
        "tail = 100 * (1 - level) / 2",
        "tail = 100 * (1 - level)",
        ("tests/experiments/test_report_interval_level.py",),
    ),
    Break(
        "statistics: ties count fully in the probability of improvement",
        "report/stats.py",
        "(a > b) + 0.5 * (a == b)",
        "(a > b) + 1.0 * (a == b)",
        ("tests/experiments/test_report.py",),
    ),
    Break(
        "statistics: the IQM trims 20%",
        "report/stats.py",
        "trim_mean(np.asarray(values, np.float64), 0.25)",
        "trim_mean(np.asarray(values, np.float64), 0.2)",
        ("tests/experiments/test_report.py",),
    ),
    Break(
        "iql: the expectile weighs the wrong side (V tracks the 1 - tau expectile)",
        "agents/iql.py",
        "torch.where(diff > 0, expectile, 1 - expectile)",
        "torch.where(diff > 0, 1 - expectile, expectile)",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: the advantage weight's sign flipped",
        "agents/iql.py",
        "torch.exp(temperature * (q - value))",
        "torch.exp(temperature * (value - q))",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: the advantage weight not clipped",
        "agents/iql.py",
        "torch.exp(temperature * (q - value)).clamp(max=max_weight)",
        "torch.exp(temperature * (q - value))",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: terminal transitions bootstrapped",
        "agents/iql.py",
        "return reward + discount * not_done * next_value",
        "return reward + discount * next_value",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: the target critic pulled the wrong way (the critic follows its target)",
        "agents/iql.py",
        "soft_update(self.critic_target.parameters(), self.critic.parameters(), s.target_rate)",
        "soft_update(self.critic.parameters(), self.critic_target.parameters(), s.target_rate)",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: the target's larger critic taken (max, not min, of Q1' and Q2')",
        "agents/iql.py",
        "self.critic_target(obs, batch.action).amin(0)",
        "self.critic_target(obs, batch.action).amax(0)",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: the critic loss of one critic only (the twin's second member never learns)",
        "agents/iql.py",
        "critic_loss = (q - target).pow(2).sum(0).mean()",
        "critic_loss = (q - target).pow(2)[0].mean()",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "iql: both critics read the first member's first layer (one network twice)",
        "agents/iql.py",
        "h = x @ first.permute(1, 0, 2).reshape(inputs, members * width)",
        "h = x @ first[0].repeat(1, members)",
        ("tests/agents/test_iql.py",),
    ),
    Break(
        "offline: a time limit taken for a terminal (no bootstrap at truncations)",
        "offline/train.py",
        "tensor(~dataset.terminations)",
        "tensor(~(dataset.terminations | dataset.truncations))",
        ("tests/offline/test_dataset_table.py",),
    ),
    Break(
        "offline: a resumed run draws other batches (the sampler's state not restored)",
        "offline/train.py",
        'self.sampler.set_state(state["sampler"])',
        "self.sampler.get_state()",
        ("tests/offline/test_offline_train.py",),
    ),
    Break(
        "offline: IQL's returns scaling spreads the returns over 100, not 1000",
        "offline/rewards.py",
        "rewards * (1000.0 / spread)",
        "rewards * (100.0 / spread)",
        ("tests/offline/test_rewards.py",),
    ),
)


def apply(source: Path, entry: Break) -> None:
    path = source / "seqrank" / entry.file
    text = path.read_text()
    found = text.count(entry.old)
    if found != 1:
        raise SystemExit(f"{entry.name}: {entry.file} holds the line {found} times, not once")
    path.write_text(text.replace(entry.old, entry.new))


def caught(entry: Break) -> bool:
    """Whether the entry's tests fail (pytest exit 1) against a broken copy of src/."""
    with tempfile.TemporaryDirectory() as scratch:
        source = Path(scratch) / "src"
        shutil.copytree(ROOT / "src", source, ignore=shutil.ignore_patterns("__pycache__"))
        apply(source, entry)
        env = dict(os.environ, PYTHONPATH=str(source), OMP_NUM_THREADS="1")
        command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider"]
        done = subprocess.run(
            [*command, *entry.tests], cwd=ROOT, env=env, capture_output=True, text=True
        )
        if done.returncode not in (0, 1):
            failure = f"pytest could not run ({done.returncode})"
            raise SystemExit(f"{entry.name}: {failure}:\n{done.stdout}")
        return done.returncode == 1


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", default="", help="entries whose name contains this text")
    parser.add_argument("--list", action="store_true", help="list the entries and stop")
    args = parser.parse_args()
    chosen = [b for b in BREAKS if args.only in b.name]
    if not chosen:
        raise SystemExit(f"no entry's name contains {args.only!r}; see --list")
    if args.list:
        print("\n".join(b.name for b in chosen))
        return 0
    missed = []
    for entry in chosen:
        verdict = "caught" if caught(entry) else "MISSED"
        print(f"{verdict:7} {entry.name}", flush=True)
        if verdict == "MISSED":
            missed.append(entry.name)
    print(f"{len(chosen) - len(missed)} of {len(chosen)} breaks caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
