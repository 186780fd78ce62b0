"""One feedback session of a training run: cut segments, ask, augment, store the labels.

Who answers is a `FeedbackSource`: a scripted teacher (B-Pref noise models), a person at
the labelling page (`seqrank.labelling.human`), or labels recorded earlier
(`seqrank.feedback.replay`). A source gets the sampled pool and the scheme's chooser and
returns the segments it actually used with the session's record; the augmentation and
storage are the same for all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from seqrank.episodes import EpisodeStore, Segments
from seqrank.feedback.checking import Recheck, standing_vouched
from seqrank.feedback.closure import AugmentationStats, augment
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import (
    Ask,
    Chooser,
    SessionRecord,
    get_scheme,
    in_order_choice,
    segments_needed,
)
from seqrank.feedback.selection import make_chooser
from seqrank.feedback.teachers import ScriptedTeacher
from seqrank.reward.model import RewardModel
from seqrank.types import Answer


@dataclass(frozen=True)
class SessionRequest:
    """What a source needs to run session `session` of `questions` questions.

    The run makes one per session and hands it to `FeedbackSource.ask_session`; most
    sources answer through `run_scheme`, which asks the run's scheme over the pool.

    Attributes:
        scheme: the run's scheme (pairwise, sequential, root or ranked).
        questions: the session's budget of questions.
        session: the session's number in the run, from 0.
        segments: the sampled candidate pool (`features`, true `rewards`, physics
            `states` when recorded); the record's segment ids index into it.
        chooser: picks each new segment from the pool (uniform, or by the reward
            ensemble's disagreement or entropy).
        rng: the session's random stream.
        margin: the scripted teachers' equal-preference margin for this session.
        recheck: noise-aware augmentation (`augment checked`); None: the paper's closure.
        episodes: with `query_episodes`, the first and last episode the pool is cut from.
        model_returns: a crowd's sessions, once the model is fit: its predicted return of
            each pooled segment, to estimate the annotators' reliability.
        chains: asked as this many chains side by side (a crowd: one per person).
        distrusted: a crowd's members flagged before the session, under `crowd_weighting`
            reask (`LabelStore.distrusted`): each of their questions is asked again of a
            member who is not; empty otherwise.
        in_order: the pool is in the order its segments were collected (`segment_order
            collection`) and is taken as it comes (`chooser` is `in_order_choice`, or a
            page's replay of the choices it stored): a crowd deals it to its chains in
            turn, and a replayed session keeps that choice.

    Examples:
        >>> import numpy as np, seqrank
        >>> from seqrank.episodes import Segments
        >>> from seqrank.feedback.schemes import uniform_choice
        >>> pool = Segments(np.zeros((4, 10, 3)), np.zeros((4, 10)), [None] * 4, [None] * 4)
        >>> rng = np.random.default_rng(0)
        >>> request = seqrank.SessionRequest("root", 3, 0, pool, uniform_choice, rng, 0.0)
        >>> record = request.run_scheme(lambda first, second: seqrank.Answer.EQUAL)
        >>> record.scheme, record.asked
        ('root', 3)
    """

    scheme: str
    questions: int
    session: int
    segments: Segments  # the sampled candidate pool
    chooser: Chooser
    rng: np.random.Generator
    margin: float  # the scripted teachers' equal-preference margin for this session
    recheck: Recheck | None = None  # noise-aware augmentation (`augment checked`)

    def run_scheme(self, ask: Ask) -> SessionRecord:
        """The session's scheme over its pool, asking `ask`."""
        scheme = get_scheme(self.scheme)
        pool = len(self.segments.rewards)
        return scheme(pool, self.questions, ask, self.rng, self.chooser, self.recheck)

    # with `query_episodes`: the numbers of the first and last episode the pool is cut from
    episodes: tuple[int, int] | None = None
    # a crowd's sessions, once the model is fit: its predicted return of each pooled
    # segment, from which the annotators' reliability is estimated (`feedback.reliability`)
    model_returns: tuple[float, ...] | None = None
    chains: int = 1  # asked as this many chains side by side (a crowd: one per person)
    # a crowd's members whose questions are asked again of someone else (reask)
    distrusted: frozenset[str] = frozenset()
    # collection order, taken as it comes: `chooser` is in_order_choice, or at a team's page
    # the stored choices replayed around it (`session_replay`)
    in_order: bool = False


class FeedbackSource(Protocol):
    """Who answers a run's questions: anything with these three methods.

    A scripted teacher, a person at the labelling page, replayed labels and
    `seqrank.JudgeSource` are sources; `train(config, out, source=...)` takes your own. The
    run samples the pool, then augments and stores what the source returns, whoever it is.

    Examples:
        >>> import numpy as np, seqrank
        >>> from seqrank.episodes import Segments
        >>> from seqrank.feedback.schemes import uniform_choice
        >>> class Script:  # prefers the larger true return
        ...     def has_session(self, session):
        ...         return True
        ...     def check_compatible(self, task, obs_dim, act_dim):
        ...         pass
        ...     def ask_session(self, request):
        ...         returns = request.segments.rewards.sum(axis=1)
        ...         def ask(first, second):
        ...             better = returns[first] > returns[second]
        ...             return seqrank.Answer.FIRST if better else seqrank.Answer.SECOND
        ...         return request.segments, request.run_scheme(ask)
        >>> rewards = np.arange(40.0).reshape(4, 10)
        >>> pool = Segments(np.zeros((4, 10, 3)), rewards, [None] * 4, [None] * 4)
        >>> rng = np.random.default_rng(0)
        >>> request = seqrank.SessionRequest("root", 3, 0, pool, uniform_choice, rng, 0.0)
        >>> segments, record = Script().ask_session(request)
        >>> record.asked, seqrank.close_preferences(record.answers).stats.answered
        (3, 3)
        >>> seqrank.train(seqrank.make_config(), "mine", source=Script())  # doctest: +SKIP
    """

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        """Answer a session.

        Args:
            request: the session's scheme, budget and pool (`SessionRequest`).

        Returns:
            The segments the record's ids index into (the request's pool, or a source's
                own), and the session's `SessionRecord`.
        """
        ...

    def has_session(self, session: int) -> bool:
        """False when this source cannot give session `session` (recorded labels ran out).

        Args:
            session: the session's number in the run, from 0.
        """
        ...

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        """Raise ValueError when this source cannot serve a run on `task` (replayed labels
        of another task, say).

        Args:
            task: the run's task name.
            obs_dim: its observation size.
            act_dim: its action size.
        """
        ...


class ScriptedSource:
    """B-Pref's scripted teacher, answering from the true rewards."""

    def __init__(self, teacher: ScriptedTeacher):
        self.teacher = teacher

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        teacher = self.teacher.with_margin(request.margin)
        rewards, rng = request.segments.rewards, request.rng

        def ask(first: int, second: int) -> Answer:
            return teacher.answer(rewards[first], rewards[second], rng)

        return request.segments, request.run_scheme(ask)


@dataclass(frozen=True)
class SessionPlan:
    """How a run's sessions are cut and chosen (the run config's feedback settings)."""

    scheme: str
    selection: str  # uniform, disagreement or entropy (after the first session)
    oversample: int  # candidate pool = this x what the scheme needs, for informative picks
    segment_length: int
    recheck: Recheck | None = None
    query_episodes: int = 0  # QPA: cut the pool from the last N episodes only (0: all kept)
    crowd: int = 0  # the members of a crowd answering the sessions (0: one teacher)
    order: str = "uniform"  # a session's new segments as drawn, or "collection": as collected


@dataclass(frozen=True)
class SessionOutcome:
    stats: AugmentationStats
    segments_used: int


def prepare_session(
    plan: SessionPlan,
    questions: int,
    episodes: EpisodeStore,
    reward_model: RewardModel,
    session: int,
    rng: np.random.Generator,
    informative: bool,
    margin: float,
    contradicted: bool = False,
    model_fit: bool = False,
) -> SessionRequest:
    """Sample the candidate pool and build the chooser for a session of `questions`.

    With an informative selection (after the first session) the candidate pool is
    `oversample` times what the scheme needs, and the chooser picks among it.

    QPA's policy-aligned query selection (Hu et al., ICLR 2024) is where the
    pool comes from, whatever the selection and scheme: with `query_episodes` N, only the
    last N episodes, those of the current policy. QPA kept 10 on DMControl
    (`max_reward_buffer_size=10` in `run_QPA.sh` of github.com/huxiao09/QPA; 30 or 60 on
    Meta-World) where PEBBLE keeps 100; 0 (the default) keeps PEBBLE's behaviour.

    `contradicted`: the teacher contradicted themselves in an earlier session
    (`LabelStore.teacher_contradicted`); `augment checked` then asks big answers twice more.
    `model_fit`: the reward model has been fit to labels; `augment checked` then does not
    ask again a teacher who has never contradicted themselves where the model agrees.

    `plan.order` "collection" gives the scheme the same segments in the order they were
    collected (`EpisodeStore.sample_segments`' `in_order`), so that later, better segments
    challenge an early root, as the paper's section D.6 counts suggest its stream did.
    """
    chains = max(1, plan.crowd)
    needed = segments_needed(plan.scheme, questions, chains)
    use_model = informative and plan.selection != "uniform"
    pool = needed * (plan.oversample if use_model else 1)
    last = plan.query_episodes
    in_order = plan.order == "collection"
    sampled = episodes.sample_segments(pool, plan.segment_length, rng, last, in_order)
    member_returns = reward_model.member_returns(sampled.features) if use_model else None
    chooser = make_chooser(plan.selection if use_model else "uniform", member_returns)
    if in_order:  # (taken as they come: a selection picking among them is refused)
        chooser = in_order_choice
    window = episodes.window(last) if last else None
    opinions = None
    if plan.crowd and model_fit:
        opinions = tuple(reward_model.member_returns(sampled.features).mean(axis=0).tolist())
    recheck = _recheck(plan.recheck, contradicted, model_fit, member_returns, sampled, reward_model)
    return SessionRequest(
        plan.scheme, questions, session, sampled, chooser, rng, margin, recheck=recheck,
        episodes=window, model_returns=opinions, chains=chains, in_order=in_order,
    )  # fmt: skip


def _recheck(
    recheck: Recheck | None,
    contradicted: bool,
    model_fit: bool,
    member_returns: np.ndarray | None,
    sampled: Segments,
    reward_model: RewardModel,
) -> Recheck | None:
    """`augment checked`'s settings for the session: told whether the teacher has
    contradicted themselves, and the fitted model's view of each candidate."""
    if recheck is not None and contradicted:
        recheck = replace(recheck, contradicted=True)
    if recheck is not None and model_fit:
        if member_returns is None:  # (an informative selection has them already)
            member_returns = reward_model.member_returns(sampled.features)
        predicted = member_returns.mean(axis=0)
        recheck = replace(recheck, model_returns=tuple(predicted.tolist()))
    return recheck


def store_session(
    segments: Segments,
    record: SessionRecord,
    labels: LabelStore,
    request: SessionRequest,
    closure: bool = True,
) -> SessionOutcome:
    """Augment the answers by transitivity (with `augment checked`, along paths of few
    unconfirmed answers) and store asked and inferred pairs; with `closure` False, the
    asked pairs alone (the reward benchmark's `--augments none`)."""
    true_returns = segments.rewards.sum(axis=1)
    recheck = request.recheck
    path_unchecked = None if recheck is None else recheck.path_unchecked
    vouched = standing_vouched(record.answers, record.vouched)
    returns = true_returns.tolist()
    augmentation = augment(record.answers, returns, path_unchecked, vouched, closure)
    labels.add_session(
        segments, true_returns, record.segments, augmentation, request.session, record
    )
    return SessionOutcome(augmentation.stats, len(record.segments))
