"""`seqrank label online|offline|study`: the labelling page, with or without training."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.label_page import (
    check_address,
    human_overrides,
    human_trainer,
    page_options,
    page_served,
    server_options,
)
from seqrank.cli.label_study import add_study, run_study
from seqrank.cli.label_team import add_gold, add_team, gold_for
from seqrank.cli.options import (
    Parser,
    add_run_options,
    positive,
    problem_with_flags,
    seed_number,
    setting_flags,
)
from seqrank.cli.train import prepare_run, say_finished
from seqrank.errors import UsageError
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP
from seqrank.feedback.schemes import SCHEMES
from seqrank.training.stopping import stop_on_signals

ROLLOUT_EPISODES = 4  # `label offline`: episodes rolled out when none are given


def add_parser(commands: Any) -> None:
    label = commands.add_parser(
        "label",
        help="the labelling page: a person answers the questions (online, offline, study)",
        description="Start a local web page where a person answers the scheme's questions. "
        "Answers are committed to labels.sqlite in the output directory before the page hears "
        "back; rerunning the same command resumes at the first unanswered question.",
    )
    modes = label.add_subparsers(dest="mode", required=True, parser_class=Parser)
    _add_online(modes)
    _add_offline(modes)
    add_study(modes)
    label.set_defaults(handler=run)


def _add_online(modes: Any) -> None:
    online = modes.add_parser(
        "online",
        help="train an agent whose teacher is the person at the page",
        description="A training run (every `seqrank train` option applies) whose feedback "
        "sessions are answered on the page. Resume a stopped run with --resume RUN_DIR.",
    )
    add_run_options(online)
    online.add_argument(
        "--no-wait",
        action="store_true",
        help="keep training while a session after the first is being answered",
    )
    add_gold(online)
    server_options(online)


def _add_offline(modes: Any) -> None:
    offline = modes.add_parser(
        "offline",
        help="label segments of saved episodes, without training",
        description="Roll out a run's saved policy (or random actions with --task), or take "
        "an offline dataset's episodes (--dataset), cut segments, and ask --sessions sessions "
        "of --questions questions.",
    )
    source = offline.add_mutually_exclusive_group()
    source.add_argument("--from", dest="policy_run", type=Path, help="a run directory to roll out")
    source.add_argument(
        "--task", help="a task acted on at random, e.g. dmc:walker_walk; with --dataset, its task"
    )
    offline.add_argument(
        "--dataset",
        help="segments of this offline dataset's episodes instead of a rollout: a Minari "
        "dataset id or folder made by `seqrank dataset make` (its clips are rendered from the "
        "physics states it keeps)",
    )
    offline.add_argument(
        "--scheme", choices=tuple(SCHEMES), default="sequential", help="how questions are asked"
    )
    offline.add_argument("--questions", type=positive, default=10, help="per session (10)")
    offline.add_argument("--sessions", type=positive, default=1, help="(1)")
    offline.add_argument(
        "--augment",
        choices=("full", "checked"),
        default="full",
        help="checked: an answer that would imply many pairs is asked again (documentation: "
        "Concepts, 'Noise-aware augmentation'); a run replaying these labels chooses its own "
        "closure",
    )
    offline.add_argument(
        "--segment-length", type=positive, help="steps (the task's: 50, block:place 30)"
    )
    offline.add_argument(
        "--episodes", type=positive, help="episodes rolled out (4; with --dataset, all of its)"
    )
    offline.add_argument(
        "--seed", type=seed_number, default=0, help="seeds the rollouts and the segments drawn (0)"
    )
    add_team(offline)
    add_gold(offline)
    offline.add_argument("--out", type=Path, help="labelling directory (default under seqrank-out)")
    offline.set_defaults(setting_flags=setting_flags(offline))
    server_options(offline)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    def say(text: str) -> None:
        err.print(text, highlight=False, markup=False, soft_wrap=True)

    page_options(args)  # check the page options before anything is created
    try:
        if args.mode == "offline":
            return _offline(args, say)
        if args.mode == "online":
            return _online(args, say, err)
        return run_study(args, say)  # it checks the address after the settings
    except (ValueError, FileNotFoundError, FileExistsError) as problem:
        raise UsageError(problem_with_flags(problem, args)) from None


def _offline_options(args: argparse.Namespace) -> Any:
    """The offline session's settings, checked before anything is written."""
    from seqrank.config import resolve_config
    from seqrank.config.rules import check_annotator_names
    from seqrank.envs import make_env
    from seqrank.labelling.app import OfflineOptions, check_task_name
    from seqrank.training.runs import RunDir

    episodes = args.episodes if args.episodes is not None else ROLLOUT_EPISODES
    if args.dataset is not None:
        task, episodes = _dataset_source(args)
    elif args.policy_run is not None:
        run = RunDir.open(args.policy_run)
        task = run.read_config().task
        if not run.checkpoint_path.exists():
            raise ValueError(f"{args.policy_run} has no checkpoint yet, so no policy to roll out")
    elif args.task is not None:
        task = check_task_name(args.task)
    else:
        raise ValueError("give the episodes to label: --from RUN, --task TASK or --dataset NAME")
    length = args.segment_length or resolve_config(task, "small", {}).segment_length
    env = make_env(task, args.seed)
    try:
        env.check_clips()
        episode = env.episode_length
    finally:
        env.close()
    if length > episode:
        raise ValueError(
            f"--segment-length {length} is longer than an episode of {task} ({episode} steps); "
            f"accepted: 1 to {episode}"
        )
    team = check_annotator_names(args.annotators, "--annotators") if args.annotators else ()
    for flag, value, default in (
        ("--overlap", args.overlap, OVERLAP),
        ("--overlap-until", args.overlap_until, EVIDENCE_UNTIL),
    ):
        if not team and value != default:
            raise ValueError(
                f"{flag} {value} acts on a team's answers; one person answers here: "
                "leave it out, or name a team with --annotators"
            )
    if args.dataset is not None:
        _check_dataset_budget(args, length, team)
    return OfflineOptions(
        task,
        args.scheme,
        args.questions,
        args.sessions,
        length,
        episodes,
        args.seed,
        args.policy_run,
        args.augment,
        team,
        args.overlap,
        args.dataset,
        args.overlap_until,
    )


def _dataset_source(args: argparse.Namespace) -> tuple[str, int]:
    """The dataset's task and episode count, checked (a task it is not of, sizes, the
    physics states its clips need); `--from` and `--episodes` refused beside it."""
    from seqrank.offline.minari_io import episodes_with_states, load_dataset

    if args.policy_run is not None or args.episodes is not None:
        given = "--from" if args.policy_run is not None else "--episodes"
        raise ValueError(f"--dataset gives the episodes to label: leave out {given}")
    episodes_with_states(args.dataset, args.task)  # refuses a dataset the page cannot show
    dataset = load_dataset(args.dataset, args.task)
    return dataset.task, dataset.episode_count


def _check_dataset_budget(args: argparse.Namespace, length: int, team: tuple[str, ...]) -> None:
    from seqrank.offline.labelling import check_budget
    from seqrank.offline.minari_io import load_dataset

    dataset = load_dataset(args.dataset, args.task)
    budget = args.questions * args.sessions
    check_budget(dataset, args.scheme, budget, args.questions, length, len(team), args.sessions)


def _offline(args: argparse.Namespace, say: Any) -> int:
    from seqrank.labelling.app import open_hub, run_offline
    from seqrank.labelling.directory import (
        check_offline_settings,
        record_offline_settings,
        take_directory,
    )
    from seqrank.labelling.human import Stopped

    options = _offline_options(args)
    gold = gold_for(args, options.task, options.segment_length, options.annotators)
    _check_address(args)  # the task and settings first: a wrong task outweighs a busy port
    default_out = (
        args.policy_run / "offline-labels"
        if args.policy_run is not None
        else Path("seqrank-out/labels") / options.task.replace(":", "-")
    )
    directory = args.out or default_out
    settings = _settings_of(options)
    lock = take_directory(directory)
    try:
        for change in check_offline_settings(directory, settings, gold):
            say(f"continuing {directory} with {change}")
        hub = open_hub(directory, options.task, page_options(args))
        if options.annotators:
            from seqrank.labelling.crowd_team import open_team

            open_team(
                hub, options.annotators, options.overlap, args.reassign_after,
                options.overlap_until, gold,
            )  # fmt: skip
        record_offline_settings(hub.db, settings)
        with stop_on_signals(hub.stop.set, say) as stop, page_served(hub, directory, args, say):
            try:
                answers = run_offline(directory, options, hub, say)
                say(f"offline labelling complete: {answers} answers")
            except (KeyboardInterrupt, Stopped):
                say("stopped; every given answer is saved; run the same command to continue")
                hub.stop.set()
    finally:
        lock.release()
    return stop.exit_code(0) if stop.received else 0


def _settings_of(options: Any) -> dict[str, Any]:
    """The settings a labelling directory keeps, by option name."""
    from dataclasses import asdict

    settings = asdict(options)
    policy = settings.pop("policy_run")
    settings["from"] = None if policy is None else str(policy)
    settings["annotators"] = list(settings["annotators"])  # as JSON gives it back
    return settings


def _check_address(args: argparse.Namespace) -> None:
    """The page's address is free (a dry run only checks the settings)."""
    if not getattr(args, "dry_run", False):
        check_address(args.host, args.port)


def check_clips(task: str) -> None:
    """A task whose clips the page could not show is refused before anything is made."""
    from seqrank.envs import make_env

    env = make_env(task)
    try:
        env.check_clips()
    finally:
        env.close()


def _online(args: argparse.Namespace, say: Any, err: Console) -> int:
    from seqrank.labelling.app import open_hub
    from seqrank.training.runs import RunDir
    from seqrank.training.runtime import resolve_device

    human_overrides(args)
    holder: dict[str, Any] = {}

    def make(config: Any, run: RunDir) -> Any:
        if "gold" not in holder:  # a resumed run: its own task's
            holder["gold"] = gold_for(args, config.task, config.segment_length, config.team)
        holder["hub"] = hub = open_hub(run.path, config.task, page_options(args))
        try:
            if config.team:
                from seqrank.labelling.crowd_team import open_team

                open_team(
                    hub, config.team, config.overlap, args.reassign_after,
                    config.overlap_until, holder.get("gold"),
                )  # fmt: skip
            return human_trainer(hub, "online", not args.no_wait, say)(config, run)
        except BaseException:
            if hub.renderer is not None:
                hub.renderer.close()
            hub.db.close()
            raise

    def check(config: Any) -> None:
        check_clips(config.task)
        holder["gold"] = gold_for(args, config.task, config.segment_length, config.team)
        _check_address(args)

    started = prepare_run(args, err, make, resolve_device, check)
    if started is None:  # --dry-run
        gold = holder.get("gold")
        if gold is not None:
            err.print(f"gold: {len(gold.pairs)} pairs from {gold.source}", soft_wrap=True)
        return 0
    try:
        if started.finished:
            say_finished(started, err)
            return 0
        return _train_online(started, holder["hub"], args, say)
    finally:
        started.run.release()


def _train_online(started: Any, hub: Any, args: argparse.Namespace, say: Any) -> int:
    from seqrank.labelling.app import train_with_person
    from seqrank.labelling.page_state import Phase
    from seqrank.training.loop import RunStopped

    trainer, path = started.trainer, started.run.path

    def stop_now() -> None:
        trainer.stop_requested.set()
        hub.stop.set()

    with stop_on_signals(stop_now, say) as stop, page_served(hub, path, args, say):
        try:
            summary = train_with_person(trainer, hub, say)
            if summary is not None:
                ended = f"training finished: eval return {summary['final_eval_return']}"
                hub.state.move(Phase.DONE, ended)
                say(f"run finished: {path}")
        except (KeyboardInterrupt, RunStopped):
            hub.stop.set()
        if stop.received or hub.stop.is_set():
            say(f"stopped; continue with: seqrank label online --resume {path}")
    return stop.exit_code(0) if stop.received else 0
