"""`seqrank label study`: the user-study protocol (D.7), one participant at a time."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from seqrank.cli.label_page import (
    check_address,
    human_overrides,
    human_trainer,
    page_options,
    page_served,
    server_options,
)
from seqrank.cli.options import add_run_options
from seqrank.cli.train import new_run
from seqrank.feedback.schemes import SCHEMES
from seqrank.training.stopping import stop_on_signals


def add_study(modes: Any) -> None:
    study = modes.add_parser(
        "study",
        help="the user-study protocol (D.7): one participant, three methods, surveys",
        description="One participant trains one agent per method (pairwise, sequential, root by "
        "default) with the same budget, in a counterbalanced order, and answers the "
        "satisfaction survey after each. Every `seqrank train` option applies to all runs.",
    )
    study.add_argument("--participant", required=True, help="participant id, e.g. p01")
    study.add_argument(
        "--study-dir",
        type=Path,
        default=Path("seqrank-out/study"),
        help="where every participant's runs and surveys are kept (seqrank-out/study)",
    )
    study.add_argument(
        "--methods",
        default=",".join(("pairwise", "sequential", "root")),
        help="schemes compared, comma-separated (each participant gets a counterbalanced order)",
    )
    study.add_argument(
        "--finetune",
        action="store_true",
        help="the fine-tuning study (Table 3: 400 steps, learning rate 1e-8, 20 answers in two "
        "sessions, 30-step clips) from the run given by --start-from; options given "
        "explicitly win",
    )
    add_run_options(study, wandb=False)
    server_options(study)


def run_study(args: argparse.Namespace, say: Any) -> int:
    from seqrank.config import resolve_config
    from seqrank.labelling.app import open_hub, study_order
    from seqrank.labelling.directory import take_directory
    from seqrank.training.runtime import resolve_device

    methods = _study_methods(args)
    human_overrides(args)
    participant_dir = args.study_dir / args.participant
    new = new_run(args, resolve_device)
    task, given = new.task, new.given
    if args.finetune:  # Table 3, and the trained run's task and sizes unless given
        preset, source = _finetune_preset(given)
        task = task if hasattr(args, "task") else source["task"]
        sizes = {k: source[k] for k in SOURCE_SIZES if k not in given and k in source}
        given = {**preset, **sizes, **given}
    configs = {  # every method's settings, checked before anything is written
        method: resolve_config(task, new.scale, {**given, "scheme": method}) for method in methods
    }
    if args.dry_run:
        say(f"settings valid for {', '.join(methods)} (dry run: nothing written)")
        return 0
    check_address(args.host, args.port)  # the settings first: a wrong one outweighs a busy port
    lock = take_directory(participant_dir, "participant directory")
    try:
        _check_started_runs(participant_dir, configs)
    except ValueError:
        lock.release()
        raise
    order = study_order(args.study_dir, args.participant, methods)
    hub = open_hub(participant_dir, new.task, page_options(args))
    hub.state.plan(0)
    driver = _Study(hub, str(new.device), participant_dir, say)
    try:
        with (
            stop_on_signals(driver.stop, say) as stop,
            page_served(hub, participant_dir, args, say),
        ):
            say(f"participant {args.participant}: methods in the order {', '.join(order)}")
            try:
                driver.run(order, configs)
            except KeyboardInterrupt:
                hub.stop.set()
            if hub.stop.is_set():
                say("stopped; rerun the same command to continue where it stopped")
    finally:
        lock.release()
    return stop.exit_code(0) if stop.received else 0


def _check_started_runs(participant_dir: Path, configs: dict[str, Any]) -> None:
    """A method's run made with other settings is named before anything starts."""
    from seqrank.config import config_differences
    from seqrank.training.runs import RunDir

    for method, config in configs.items():
        if (participant_dir / method / "config.json").is_file():
            saved = RunDir.open(participant_dir / method).read_config()
            changed = config_differences(saved, config)
            if changed:
                raise ValueError(
                    f"participant {participant_dir.name} began method {method} with other "
                    f"settings ({'; '.join(changed)}); rerun with them to continue"
                )


class _Study:
    """One participant's methods in order, each trained (or continued) then surveyed."""

    def __init__(self, hub: Any, device: str, directory: Path, say: Any):
        self.hub, self.device, self.directory, self.say = hub, device, directory, say
        self.trainer: Any = None

    def stop(self) -> None:
        self.hub.stop.set()
        if self.trainer is not None:
            self.trainer.stop_requested.set()

    def run(self, order: list[str], configs: dict[str, Any]) -> None:
        from seqrank.labelling.app import wait_survey
        from seqrank.labelling.page_state import Phase

        for method in order:
            if not self.train(method, configs[method]):
                return
            if not wait_survey(self.hub, method, method):
                return
        self.hub.state.move(Phase.DONE, "the study is complete: thank you")
        self.say(f"participant {self.directory.name} finished all methods")

    def train(self, method: str, config: Any) -> bool:
        """Train, continue or (when finished) skip one method's run; False when stopped."""
        from seqrank.labelling.app import train_with_person
        from seqrank.training.launch import open_or_start
        from seqrank.training.loop import RunStopped

        run_path = self.directory / method
        build = human_trainer(self.hub, method, True, self.say)
        started = open_or_start(run_path, config, self.device, build)
        try:
            if started.finished:
                return True
            self.trainer = started.trainer
            self.say(f"method {method}: training in {run_path}")
            return train_with_person(started.trainer, self.hub, self.say) is not None
        except RunStopped:
            return False
        finally:
            self.trainer = None
            started.run.release()


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


# what a fine-tuning run takes from the run it starts from unless given
SOURCE_SIZES = ("hidden", "layers", "reward_hidden", "reward_layers", "reward_ensemble")


def _finetune_preset(given: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Table 3's settings and the saved settings of the run given by --start-from."""
    from seqrank.training.finetune import FINETUNE_PRESET

    if not given.get("start_from"):
        raise ValueError("--finetune starts each method from a trained run: give --start-from RUN")
    saved = Path(given["start_from"]) / "config.json"
    if not saved.is_file():
        raise ValueError(
            f"--start-from {given['start_from']}: not a run directory (no config.json)"
        )
    return FINETUNE_PRESET, json.loads(saved.read_text())
