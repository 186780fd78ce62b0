"""Labels over a fixed dataset's segments, a reward model fit to them, and the dataset
relabelled by it.

The questions are asked exactly as a training run (and the reward benchmark) asks them:
sessions of `session_questions` (`prepare_session`: segments cut uniformly, a uniform
episode and a uniform start within it), any teacher `make_source` knows (scripted
presets, a simulated crowd, `replay:FILE`), the scheme's transitive closure stored by
`store_session`. The scripted teachers' equal-preference margin is B-Pref's: the
dataset's mean return per step, times the segment length.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from seqrank.errors import SettingError, setting
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import SchemeName, segments_needed
from seqrank.feedback.session import FeedbackSource, SessionPlan, prepare_session, store_session
from seqrank.feedback.teachers import parse_teacher
from seqrank.offline.dataset import OfflineDataset
from seqrank.reward.model import RewardModel
from seqrank.rewardbench.bench import RewardNet

CPU = torch.device("cpu")


def label_dataset(
    dataset: OfflineDataset,
    scheme: str,
    teacher: str,
    budget: int,
    session_questions: int = 25,
    segment_length: int = 50,
    seed: int = 0,
    source: FeedbackSource | None = None,
) -> LabelStore:
    """`budget` questions of `scheme` about the dataset's segments, answered by `teacher`
    (a `--teacher` value; `source`, when given, answers instead: the labelling page, your
    own), in sessions of `session_questions`; the asked and inferred pairs.

    A ValueError names a bad scheme, teacher or size, and a budget larger than the
    dataset's distinct segments of that length can give. A replayed file that runs out
    ends the labelling early.
    """
    schemes = [s.value for s in SchemeName]
    if scheme not in schemes:
        raise ValueError(f"unknown scheme {scheme!r}; accepted: {', '.join(schemes)}")
    for name, value in (("budget", budget), ("session_questions", session_questions),
                        ("segment_length", segment_length)):  # fmt: skip
        if value < 1:
            raise ValueError(f"{name} must be at least 1, got {value}")
    spec = parse_teacher(teacher)
    crowd = len(spec.members) if spec.kind == "crowd" else 0
    check_budget(dataset, scheme, budget, session_questions, segment_length, crowd)
    if source is None:
        from seqrank.feedback.sources import make_source

        source = make_source(teacher)
    source.check_compatible(dataset.task, dataset.obs_dim, dataset.act_dim)
    plan = SessionPlan(scheme, "uniform", 1, segment_length, crowd=crowd)
    episodes = dataset.episode_store()
    margin = segment_margin(dataset, segment_length)
    rng = np.random.default_rng(seed)
    # read only by informative selection and a crowd's opinions after a fit: neither here
    unread_model = RewardModel(1, dataset.obs_dim + dataset.act_dim, 1, 1, 1e-3, CPU)
    labels, asked, session = LabelStore(), 0, 0
    while asked < budget and source.has_session(session):
        questions = min(session_questions, budget - asked)
        request = prepare_session(
            plan, questions, episodes, unread_model, session, rng, False, margin
        )
        segments, record = source.ask_session(request)
        asked += store_session(segments, record, labels, request).stats.asked
        session += 1
    return labels


def segment_margin(dataset: OfflineDataset, segment_length: int) -> float:
    """B-Pref's margin: the dataset's mean return per step, over a segment."""
    return float(dataset.rewards.astype(np.float64).mean()) * segment_length


def distinct_segments(dataset: OfflineDataset, segment_length: int) -> int:
    """How many different segments of `segment_length` the dataset's episodes hold (one
    per start; an episode shorter than a segment gives one, its whole self)."""
    lengths = np.diff(np.append(dataset.starts, len(dataset)))
    return int(np.maximum(lengths - segment_length, 0).sum() + len(lengths))


def segment_limit(dataset: OfflineDataset) -> tuple[int, bool]:
    """The longest segment the dataset's episodes take, and whether an episode that ends
    without a terminal state sets it. `EpisodeStore.sample_segments` pads an episode
    shorter than a segment as an absorbing terminal state would show: right only after a
    terminal state, so the limit is the shortest episode that was cut (a time limit),
    or where every episode ends in a terminal state, the longest one."""
    stops = np.append(dataset.starts[1:], len(dataset))
    lengths, cut = stops - dataset.starts, ~dataset.terminations[stops - 1]
    return (int(lengths[cut].min()), True) if cut.any() else (int(lengths.max()), False)


def check_segment_length(dataset: OfflineDataset, segment_length: int) -> None:
    """A SettingError naming the longest accepted when segments would be padded where
    no terminal state is."""
    limit, cut = segment_limit(dataset)
    if segment_length <= limit:
        return
    name = dataset.meta.get("dataset_id") or dataset.meta.get("path") or ""
    which = (
        f"the shortest episode of dataset {name} that ends without a terminal state "
        f"({limit} steps; a segment is padded only past a terminal state)"
        if cut
        else f"every episode of dataset {name} (the longest has {limit} steps)"
    )
    raise SettingError(
        f"{setting('segment_length')} {segment_length} is longer than {which}; "
        f"accepted: 1 to {limit}"
    )


def check_budget(
    dataset: OfflineDataset,
    scheme: str,
    budget: int,
    session_questions: int,
    segment_length: int,
    crowd: int = 0,
    sessions: int | None = None,
) -> None:
    """A ValueError when a segment is longer than the dataset's episodes allow
    (`check_segment_length`), or the questions would need more segments than the dataset
    holds (segments are drawn with replacement, so a session near that many repeats itself).
    It names the settings and the largest accepted: `max_feedback` in sessions of
    `session_questions` (offline train), or with `sessions` given, `sessions` sessions of
    `questions` (the labelling page's `label offline`)."""
    check_segment_length(dataset, segment_length)
    chains = max(1, crowd)
    needed = _segments_for(scheme, budget, session_questions, chains)
    available = distinct_segments(dataset, segment_length)
    if needed <= available:
        return
    if sessions is None:
        asked = (
            f"{setting('max_feedback')} {budget}, "
            f"{setting('session_questions')} {session_questions}"
        )
        most = _largest_budget(scheme, budget, session_questions, chains, available)
        accepted = f"{setting('max_feedback')} 1 to {most}"
    else:
        asked = f"--questions {session_questions} x --sessions {sessions}"
        per_session = _segments_for(scheme, session_questions, session_questions, chains)
        most = available // per_session
        accepted = f"--sessions 1 to {most} with --questions {session_questions}"
        if not most:
            fewer = _largest_budget(scheme, session_questions, session_questions, chains, available)
            accepted = f"--questions 1 to {fewer} with --sessions 1"
    raise SettingError(
        f"a budget of {budget} {scheme} questions ({asked}) needs {needed} segments of "
        f"{segment_length} steps; dataset {dataset.meta.get('dataset_id') or ''} holds "
        f"{available} distinct ones ({dataset.episode_count} episodes, {len(dataset)} steps); "
        f"accepted: {accepted}, or a larger dataset"
    )


def _segments_for(scheme: str, budget: int, session_questions: int, chains: int) -> int:
    """The segments `budget` questions in sessions of `session_questions` may draw."""
    full, last = divmod(budget, session_questions)
    needed = full * segments_needed(scheme, session_questions, chains)
    return needed + (segments_needed(scheme, last, chains) if last else 0)


def _largest_budget(
    scheme: str, budget: int, session_questions: int, chains: int, available: int
) -> int:
    """The largest budget up to `budget` whose segments the dataset holds (0: none)."""
    low, high = 0, budget  # the segments needed grow with the budget: bisect
    while low < high:
        middle = (low + high + 1) // 2
        if _segments_for(scheme, middle, session_questions, chains) <= available:
            low = middle
        else:
            high = middle - 1
    return low


def save_labels(
    labels: LabelStore,
    dataset: OfflineDataset,
    path: Path | str,
    scheme: str,
    teacher: str,
    segment_length: int,
) -> int:
    """The labels as a label file (`feedback.label_file`: the segments of every question
    and the questions in order; `seqrank labels`, `reward-bench score` and `replay:FILE`
    read it); the number of answers written."""
    from seqrank.dirs import check_file
    from seqrank.feedback.label_file import store_lines

    path = Path(path)
    check_file(path, "label file")
    header = {
        "task": dataset.task,
        "obs_dim": dataset.obs_dim,
        "act_dim": dataset.act_dim,
        "segment_length": segment_length,
        "dataset": dataset.meta.get("dataset_id"),
    }
    lines = list(store_lines(labels, header, "offline", scheme, teacher))
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".part")
    partial.write_text("".join(line + "\n" for line in lines))
    os.replace(partial, path)  # a reader never sees half a file
    return sum('"type": "answer"' in line for line in lines)


def fit_reward(
    dataset: OfflineDataset,
    labels: LabelStore,
    net: RewardNet | None = None,
    seed: int = 0,
) -> RewardModel:
    """The reward ensemble (`net`: the small preset's 3 x 256 x 3, lr 3e-4 by default)
    fit to every label by Bradley-Terry, with the run's early stop; a ValueError when
    there is no label (every answer a skip)."""
    if not len(labels):
        raise ValueError("no labels to fit the reward to (every answer was a skip)")
    net = net if net is not None else RewardNet()
    torch.manual_seed(seed)
    features = dataset.obs_dim + dataset.act_dim
    model = RewardModel(net.ensemble, features, net.hidden, net.layers, net.lr, CPU)
    generator = torch.Generator().manual_seed(seed)
    model.train(
        *labels.tensors(CPU), net.epochs, net.minibatch, net.stop_accuracy, generator,
        sync_every_step=False,
    )  # fmt: skip
    return model


@torch.no_grad()
def relabel(dataset: OfflineDataset, model: RewardModel, chunk: int = 65_536) -> OfflineDataset:
    """The dataset with every transition's reward the ensemble's mean prediction (the true
    reward stays in `meta["true_return_mean"]` only as a summary)."""
    rewards = np.empty(len(dataset), np.float32)
    for start in range(0, len(dataset), chunk):
        rows = slice(start, start + chunk)
        obs = torch.as_tensor(dataset.observations[rows], device=model.device)
        action = torch.as_tensor(dataset.actions[rows], device=model.device)
        rewards[rows] = model.reward(obs, action)[:, 0].cpu().numpy()
    meta = {**dataset.meta, "rewards": "learned",
            "true_return_mean": float(dataset.episode_returns().mean())}  # fmt: skip
    return replace(dataset, rewards=rewards, meta=meta)
