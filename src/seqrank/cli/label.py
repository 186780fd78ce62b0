"""`seqrank label online|offline|study`: the labelling page, with or without training."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import Parser, add_run_options, positive
from seqrank.cli.train import new_run, prepare_run
from seqrank.errors import UsageError
from seqrank.feedback.schemes import SCHEMES
from seqrank.labelling import CLIP_SIZE

SERVER_HELP = "labelling page options"


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
    _add_study(modes)
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
    _server_options(online)


def _add_offline(modes: Any) -> None:
    offline = modes.add_parser(
        "offline",
        help="label segments of saved episodes, without training",
        description="Roll out a run's saved policy (or random actions with --task), cut "
        "segments, and ask --sessions sessions of --questions questions.",
    )
    source = offline.add_mutually_exclusive_group(required=True)
    source.add_argument("--from", dest="policy_run", type=Path, help="a run directory to roll out")
    source.add_argument("--task", help="a task acted on at random, e.g. dmc:walker_walk")
    offline.add_argument("--scheme", choices=tuple(SCHEMES), default="sequential")
    offline.add_argument("--questions", type=positive, default=10, help="per session (10)")
    offline.add_argument("--sessions", type=positive, default=1, help="(1)")
    offline.add_argument(
        "--segment-length", type=positive, help="steps (the task's: 50, block:place 30)"
    )
    offline.add_argument("--episodes", type=positive, default=4, help="episodes rolled out (4)")
    offline.add_argument("--seed", type=int, default=0)
    offline.add_argument("--out", type=Path, help="labelling directory (default under seqrank-out)")
    _server_options(offline)


def _add_study(modes: Any) -> None:
    study = modes.add_parser(
        "study",
        help="the user-study protocol (D.7): one participant, three methods, surveys",
        description="One participant trains one agent per method (pairwise, sequential, root by "
        "default) with the same budget, in a counterbalanced order, and answers the "
        "satisfaction survey after each. Every `seqrank train` option applies to all runs.",
    )
    study.add_argument("--participant", required=True, help="participant id, e.g. p01")
    study.add_argument("--study-dir", type=Path, default=Path("seqrank-out/study"))
    study.add_argument("--methods", default=",".join(("pairwise", "sequential", "root")))
    add_run_options(study, wandb=False)
    _server_options(study)


def _server_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(SERVER_HELP)
    group.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (127.0.0.1); any other needs a token, made if not given",
    )
    group.add_argument("--port", type=int, default=8765, help="(8765; 0 picks a free port)")
    group.add_argument(
        "--token", help="access token the page must carry (16+ characters beyond 127.0.0.1)"
    )
    group.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="another name or address the page is opened by (e.g. a public IP in front of "
        "this machine); others are refused (DNS-rebinding defence)",
    )
    group.add_argument(
        "--countdown", type=float, default=3.0, help="seconds per question (3, as D.7; 0: none)"
    )
    group.add_argument("--annotator", default="anonymous", help="stored with every answer")
    group.add_argument("--fps", type=positive, default=30, help="clip frame rate (30)")
    group.add_argument(
        "--size", type=positive, default=CLIP_SIZE, help=f"clip width and height ({CLIP_SIZE})"
    )
    group.add_argument(
        "--keep-serving", action="store_true", help="keep the page up after the last answer"
    )


def _server(args: argparse.Namespace) -> Any:
    from seqrank.labelling.access import page_token
    from seqrank.labelling.app import ServerOptions

    if args.countdown < 0:
        raise UsageError(f"--countdown {args.countdown}: must be 0 (none) or more seconds")
    try:
        page_token(args.host, args.token)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    return ServerOptions(
        args.host,
        args.port,
        args.token,
        args.countdown,
        args.annotator,
        args.fps,
        args.size,
        allowed_hosts=tuple(args.allow_host),
    )


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    def say(text: str) -> None:
        err.print(text, highlight=False)

    _server(args)  # check the page options before anything is created
    try:
        if args.mode == "offline":
            return _offline(args, say)
        if args.mode == "online":
            return _online(args, say, err)
        return _study(args, say)
    except (ValueError, FileNotFoundError, FileExistsError) as problem:
        raise UsageError(str(problem)) from None


def _serve(hub: Any, args: argparse.Namespace, say: Any) -> Any:
    from seqrank.labelling.app import PageServer

    server = PageServer(hub, _server(args))
    server.start()
    say(f"labelling page: {server.url}")
    if server.remote_url is not None:
        say(f"from other machines: {server.remote_url}")
    return server


def _finish(hub: Any, server: Any, directory: Path, args: argparse.Namespace, say: Any) -> None:
    from seqrank.labelling.app import close_hub

    try:
        if args.keep_serving and not hub.stop.is_set():
            say("all done; the page stays up until Ctrl-C")
            while True:
                time.sleep(1)
        else:
            time.sleep(1.5)  # let the page show that it is done
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        close_hub(hub, directory, say)


def _offline(args: argparse.Namespace, say: Any) -> int:
    from seqrank.labelling.app import OfflineOptions, check_task_name, open_hub, run_offline
    from seqrank.training.runs import RunDir

    if args.policy_run is not None:
        task = RunDir.open(args.policy_run).read_config().task
        default_out = args.policy_run / "offline-labels"
    else:
        task = check_task_name(args.task)
        default_out = Path("seqrank-out/labels") / task.replace(":", "-")
    directory = args.out or default_out
    from seqrank.config import resolve_config

    length = args.segment_length or resolve_config(task, "small", {}).segment_length
    options = OfflineOptions(
        task,
        args.scheme,
        args.questions,
        args.sessions,
        length,
        args.episodes,
        args.seed,
        args.policy_run,
    )
    hub = open_hub(directory, task, _server(args))
    server = _serve(hub, args, say)
    try:
        answers = run_offline(directory, options, hub, say)
        say(f"offline labelling complete: {answers} answers")
    except KeyboardInterrupt:
        say("interrupted; every given answer is saved; run the same command to continue")
        hub.stop.set()
    _finish(hub, server, directory, args, say)
    return 0


def _human_trainer(hub: Any, run_name: str, wait: bool, say: Any) -> Any:
    from seqrank.labelling.app import record_task, training_progress
    from seqrank.labelling.human import HumanSource
    from seqrank.training.trainer import Trainer

    def build(config: Any, run: Any) -> Any:
        trainer = Trainer(
            config,
            run,
            source=HumanSource(hub, run_name, config.seed),
            wait_for_feedback=wait,
        )
        env = trainer.env
        record_task(hub.db, config.task, env.obs_dim, env.act_dim, config.segment_length)
        trainer.progress = training_progress(hub, config, say)
        hub.sessions_total = config.sessions
        return trainer

    return build


def _human_overrides(args: argparse.Namespace) -> None:
    if hasattr(args, "resume"):
        return
    if getattr(args, "teacher", "human") != "human":
        raise ValueError(f"--teacher {args.teacher}: the labelling page's teacher is the person")
    args.teacher, args.record_states = "human", 1


def _online(args: argparse.Namespace, say: Any, err: Console) -> int:
    from seqrank.labelling.app import open_hub, train_with_person
    from seqrank.training.runs import RunDir
    from seqrank.training.runtime import resolve_device

    _human_overrides(args)
    holder: dict[str, Any] = {}

    def make(config: Any, run: RunDir) -> Any:
        holder["hub"] = hub = open_hub(run.path, config.task, _server(args))
        return _human_trainer(hub, "online", not args.no_wait, say)(config, run)

    trainer, _config, run = prepare_run(args, err, make, resolve_device)
    hub = holder["hub"]
    server = _serve(hub, args, say)
    try:
        summary = train_with_person(trainer, hub, say)
        if summary is not None:
            hub.set_phase("done", f"training finished: eval return {summary['final_eval_return']}")
            say(f"run finished: {run.path}")
    except KeyboardInterrupt:
        say(f"interrupted; resume with: seqrank label online --resume {run.path}")
    _finish(hub, server, run.path, args, say)
    return 0


def _study(args: argparse.Namespace, say: Any) -> int:
    from seqrank.config import resolve_config
    from seqrank.labelling.app import open_hub, study_order, wait_survey
    from seqrank.training.runtime import resolve_device

    methods = _study_methods(args)
    _human_overrides(args)
    participant_dir = args.study_dir / args.participant
    order = study_order(args.study_dir, args.participant, methods)
    new = new_run(args, resolve_device)
    hub = open_hub(participant_dir, new.task, _server(args))
    hub.sessions_total = 0
    server = _serve(hub, args, say)
    say(f"participant {args.participant}: methods in the order {', '.join(order)}")
    try:
        for method in order:
            run_path = participant_dir / method
            config = resolve_config(new.task, new.scale, {**new.given, "scheme": method})
            done = (run_path / "summary.json").exists()
            if not done and not _study_train(hub, config, str(new.device), run_path, say):
                break
            if not wait_survey(hub, method, method):
                break
        else:
            hub.set_phase("done", "the study is complete: thank you")
            say(f"participant {args.participant} finished all methods")
    except KeyboardInterrupt:
        say("interrupted; rerun the same command to continue where it stopped")
    _finish(hub, server, participant_dir, args, say)
    return 0


def _study_methods(args: argparse.Namespace) -> tuple[str, ...]:
    if hasattr(args, "resume") or hasattr(args, "out") or hasattr(args, "scheme"):
        raise ValueError(
            "study runs live in --study-dir/<participant>/<method>: drop --resume/--out/--scheme "
            "(rerun the same command to continue)"
        )
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    unknown = [m for m in methods if m not in SCHEMES] or ([] if methods else ["(none)"])
    if unknown or len(set(methods)) != len(methods):
        raise ValueError(
            f"--methods {args.methods!r}: give distinct schemes from {', '.join(SCHEMES)}"
        )
    return methods


def _study_train(hub: Any, config: Any, device: str, run_path: Path, say: Any) -> bool:
    """Train (or resume) one method's run; False when the person stopped it."""
    from seqrank.labelling.app import train_with_person
    from seqrank.training.runs import RunDir
    from seqrank.training.trainer import open_trainer

    if (run_path / "config.json").exists():
        run = RunDir.open(run_path)
        config = run.read_config()
    else:
        run = RunDir.create(run_path, config, device)
    method = run_path.name  # runs live in <study-dir>/<participant>/<method>
    trainer, _ = open_trainer(_human_trainer(hub, method, True, say), config, run)
    say(f"method {method}: training in {run_path}")
    return train_with_person(trainer, hub, say) is not None
