"""Running the labelling page: the web server thread and the three drivers.

- online: a training run whose teacher is the person at the page (`HumanSource`).
- offline: sessions over segments cut from episodes of a saved run's policy (or of an offline
  dataset), no training.
- study: the D.7 protocol, one online run per method for one participant, each followed by
  the satisfaction survey.

The driver runs in the main thread; uvicorn serves the page from a second thread; clips are
rendered on a third (see clips.py). All three share one `Hub` and one database.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.config import TrainConfig
from seqrank.envs import canonical_task, make_env, same_task
from seqrank.envs.recorder import EpisodeRecorder
from seqrank.episodes import EpisodeStore
from seqrank.feedback.checking import Recheck, contradicts_itself
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP
from seqrank.feedback.schemes import segments_needed
from seqrank.feedback.selection import make_chooser
from seqrank.feedback.session import SessionRequest
from seqrank.labelling import CLIP_SIZE
from seqrank.labelling.access import Access, is_wildcard, page_token
from seqrank.labelling.clips import ClipRenderer
from seqrank.labelling.crowd_keys import GOLD_RUN
from seqrank.labelling.db import LabelDB, from_blob
from seqrank.labelling.human import Hub, PageSettings, Stopped
from seqrank.labelling.jsonl import export_file
from seqrank.labelling.page_state import Phase
from seqrank.labelling.streams import Stream, stream
from seqrank.types import Answer

Say = Callable[[str], None]
LABELS_FILE = "labels.jsonl"


@dataclass
class ServerOptions:
    host: str = "127.0.0.1"
    port: int = 8765  # 0: any free port
    token: str | None = None
    countdown_s: float = 3.0
    annotator: str = "anonymous"
    fps: int = 30
    size: int = CLIP_SIZE
    allowed_hosts: tuple[str, ...] = ()  # more names the page is reached by (Host check)
    playback: str = "side-by-side"  # or "one-after-another"


class PageServer:
    """uvicorn in a background thread; `url` is the address to open on this machine, and
    `remote_url` (when listening on every address) the one for other machines."""

    def __init__(self, hub: Hub, options: ServerOptions):
        import uvicorn

        from seqrank.labelling.server import create_app

        family = socket.AF_INET6 if ":" in options.host else socket.AF_INET
        self._socket = socket.socket(family, socket.SOCK_STREAM)
        self._socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._socket.bind((options.host, options.port))
        except OSError as error:
            raise ValueError(
                f"cannot listen on {options.host}:{options.port} ({error.strerror}); "
                "choose another --port (0 picks a free one)"
            ) from None
        port = self._socket.getsockname()[1]
        token = hub.settings.token
        access = Access.serving(options.host, port, token, options.allowed_hosts, hub.mode.tokens())
        app = create_app(hub, access)
        # log_config None: the page's server leaves the process's logging as it found it
        # (uvicorn's own config replaces every handler, closing those of other libraries,
        # dm_control's absl handler among them, and whatever stream they hold)
        config = uvicorn.Config(app, log_level="warning", lifespan="off", log_config=None)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [self._socket]}, daemon=True
        )
        query = f"?token={token}" if token else ""
        wildcard = is_wildcard(options.host)
        host = ("::1" if ":" in options.host else "127.0.0.1") if wildcard else options.host
        host = f"[{host}]" if ":" in host else host
        self.base = f"http://{host}:{port}/"
        self.remote_base = f"http://{socket.gethostname()}:{port}/" if wildcard else None
        self.url = f"{self.base}{query}"
        self.remote_url = None if self.remote_base is None else f"{self.remote_base}{query}"
        self.port = port
        self.hub = hub

    def announce(self) -> list[str]:
        """The lines that say where the page is (a team's: each person's address)."""
        return self.hub.mode.announce(
            base=self.base, url=self.url, remote_base=self.remote_base, remote_url=self.remote_url
        )

    def start(self) -> None:
        self._thread.start()
        deadline = time.monotonic() + 30
        while not self._server.started and time.monotonic() < deadline:
            time.sleep(0.02)

    def stop(self) -> None:
        self._server.should_exit = True
        self._thread.join(timeout=10)
        self._socket.close()


def open_hub(directory: Path, task: str, options: ServerOptions) -> Hub:
    """The database in `directory` and a renderer for `task`'s clips."""
    db = LabelDB.in_dir(directory)
    token = page_token(options.host, options.token)
    settings = PageSettings(options.countdown_s, options.annotator, token, options.playback)
    hub = Hub(db, settings)
    if canonical_task(task)[0] in ("gym", "custom"):  # the others all re-render from state
        probe = make_env(task, 0)
        hub.clip_source = probe.clip_source
        probe.close()

    def make_frames() -> tuple[Callable[[int], np.ndarray], Callable[[], None]]:
        env = make_env(task, 0)
        env.use_fast_rendering()

        def frames(segment_id: int) -> np.ndarray:
            row = db.segment(segment_id)
            if row is None or row["states"] is None:
                raise ValueError(f"segment {segment_id} has no saved states")
            return env.render_states(
                from_blob(row["states"]), row["context"], options.size, options.size
            )

        return frames, env.close

    hub.renderer = ClipRenderer(directory / "clips", make_frames, options.fps)
    return hub


def record_task(db: LabelDB, task: str, obs_dim: int, act_dim: int, segment_length: int) -> None:
    values = {"task": task, "obs_dim": obs_dim, "act_dim": act_dim}
    values["segment_length"] = segment_length
    for key, value in values.items():
        stored = db.get_meta(key)
        if key == "task" and stored is not None and same_task(json.loads(stored), task):
            continue  # (the name it began with is kept: walker_walk is dmc:walker_walk)
        if stored is not None and json.loads(stored) != value:
            raise ValueError(
                f"{db.path} holds labels for {key} {json.loads(stored)!r}, not {value!r}"
            )
        db.set_meta(key, json.dumps(value))


def close_hub(hub: Hub, directory: Path, say: Say) -> None:
    """Write the export, then end the clip renderer and close the database (even when the
    export fails: a renderer left running crashes the process at exit)."""
    hub.stop.set()
    try:
        answers = export_file(hub.db, directory / LABELS_FILE)
        gold = len(hub.db.answered_questions(GOLD_RUN))
        kept = f" ({gold} answers to gold pairs in the database only)" if gold else ""
        say(f"{answers} answers saved in {hub.db.path} and {directory / LABELS_FILE}{kept}")
    finally:
        if hub.renderer is not None:
            hub.renderer.close()
        hub.db.close()


# ---- offline -----------------------------------------------------------------------
@dataclass
class OfflineOptions:
    task: str
    scheme: str
    questions: int
    sessions: int
    segment_length: int
    episodes: int
    seed: int
    policy_run: Path | None  # a run directory whose saved policy acts; None: random actions
    augment: str = "full"  # checked: answers that would imply many pairs are asked again
    annotators: tuple[str, ...] = ()  # a team sharing the sessions out (empty: one person)
    overlap: float = OVERLAP  # a team's share of answers also asked of a second annotator
    dataset: str | None = None  # an offline dataset whose episodes are labelled (no rollout)
    # a team: every answer of a member with fewer answers shared with somebody else is
    # asked again of two others (`seqrank.feedback.overlap`)
    overlap_until: int = EVIDENCE_UNTIL


def rollout_episodes(options: OfflineOptions, say: Say) -> EpisodeStore:
    """Episodes with their physics states, acted by a run's saved policy or at random, or
    an offline dataset's (which keeps its physics states)."""
    import torch

    if options.dataset is not None:
        from seqrank.offline.minari_io import episodes_with_states

        taken = episodes_with_states(options.dataset, options.task)
        say(f"{len(taken)} episodes of dataset {options.dataset}")
        store = EpisodeStore(len(taken))
        for episode in taken:
            store.add(episode)
        return store

    env = make_env(options.task, options.seed)
    agent = _saved_policy(options.policy_run, env) if options.policy_run else None
    rng = stream(options.seed, Stream.ROLLOUT)
    generator = torch.Generator().manual_seed(options.seed)
    store = EpisodeStore(options.episodes)
    recorder = EpisodeRecorder(record_states=True)  # the clips are rendered from states
    for number in range(options.episodes):
        obs, info = env.reset(seed=int(rng.integers(2**31)))
        done = False
        while not done:
            if agent is None:
                action = rng.uniform(-1.0, 1.0, env.act_dim).astype(np.float32)
            else:
                action = agent.act(obs, False, generator)
            action = env.canonical_action(action)
            recorder.before_step(env)
            next_obs, reward, terminated, truncated, _ = env.step(action)
            recorder.add(obs, action, float(reward))
            obs, done = next_obs, terminated or truncated
        store.add(recorder.finish(info.get("task_index")))
        say(f"episode {number + 1}/{options.episodes} rolled out")
    env.close()
    return store


def _saved_policy(run_dir: Path, env: Any) -> Any:
    from seqrank.training.agent_factory import load_policy

    return load_policy(run_dir, env)


def _recheck(db: LabelDB, session: int) -> Recheck:
    """`checked`'s settings for `session`: big answers are asked twice more once the
    labeller has contradicted themselves, earlier in the session (the scheme sees that) or
    in an earlier session (read here from earlier sessions only, so that a session resumed
    after a crash asks what it asked before)."""
    asked = db.answered_questions("offline")
    earlier = ((q.first, q.second, Answer(a.answer)) for q, a in asked if q.session < session)
    return Recheck(contradicted=contradicts_itself(earlier))


def run_offline(directory: Path, options: OfflineOptions, hub: Hub, say: Say) -> int:
    """Ask every session not yet complete; returns the number of answers in the database."""
    db = hub.db
    env = make_env(options.task, options.seed)
    record_task(db, options.task, env.obs_dim, env.act_dim, options.segment_length)
    env.close()
    hub.state.plan(options.sessions)
    source = hub.source("offline", options.seed)
    episodes: EpisodeStore | None = None
    chains = max(1, len(options.annotators))
    needed = segments_needed(options.scheme, options.questions, chains)
    for session in range(options.sessions):
        stored = db.session_row("offline", session)
        if stored is not None and db.count("offline", session) >= stored["questions"]:
            continue
        rng = stream(options.seed, Stream.OFFLINE_SESSION, session)
        if stored is not None:
            pool = db.pool("offline", session)
        else:
            if episodes is None:
                hub.state.move(Phase.WAITING, "preparing the clips")
                episodes = rollout_episodes(options, say)
            pool = episodes.sample_segments(needed, options.segment_length, rng)
        request = SessionRequest(
            options.scheme,
            options.questions,
            session,
            pool,
            make_chooser("uniform", None),
            rng,
            0.0,
            recheck=_recheck(db, session) if options.augment == "checked" else None,
            chains=chains,
        )
        say(f"session {session + 1}/{options.sessions}: {options.questions} questions")
        source.ask_session(request)
        export_file(db, directory / LABELS_FILE)
    hub.state.move(Phase.DONE, "all sessions are answered: thank you")
    return len(db.answered_questions())


# ---- online and study ----------------------------------------------------------------
def training_progress(
    hub: Hub, config: TrainConfig, say: Say
) -> Callable[[int, dict[str, Any]], None]:
    def report(step: int, live: dict[str, Any]) -> None:
        ret = live["eval_return"]
        text = (
            f"step {step:,} of {config.steps:,}; eval return {'-' if ret is None else f'{ret:.1f}'}"
        )
        hub.state.show_training(
            f"the agent is training: {text}", lambda: hub.mode.still_asking(hub)
        )
        if step % config.eval_every == 0 and ret is not None:
            hub.state.add_eval(step, float(ret))
        if step % config.eval_every == 0:
            say(f"{text}; asked {live['asked']}, inferred {live['inferred']}")

    return report


def train_with_person(trainer: Any, hub: Hub, say: Say) -> dict[str, Any] | None:
    """Train; None when the server was stopped while a question was waiting."""
    try:
        summary: dict[str, Any] = trainer.train()
        return summary
    except Stopped:
        say("stopped while waiting for an answer; every given answer is saved")
        return None


def wait_survey(hub: Hub, run: str, scheme: str) -> bool:
    """Open the survey for `run` and wait for it; False if stopped first."""
    db = hub.db
    if db.survey(run) is not None:
        return True
    hub.state.open_survey(run, scheme, f"survey about the {scheme} method")
    answered = False
    with db.changed:
        while not hub.stop.is_set() and not (answered := db.survey(run) is not None):
            db.changed.wait(0.5)
    if answered:  # (out of the database's lock: the page state's is taken first elsewhere)
        hub.state.close_survey()
    return answered


STUDY_SCHEMES = ("pairwise", "sequential", "root")


def study_order(study_dir: Path, participant: str, schemes: tuple[str, ...]) -> list[str]:
    """Counterbalanced method order: participants take the orderings in turn (a Latin cycle)."""
    path = study_dir / participant / "study.json"
    if path.exists():
        order: list[str] = json.loads(path.read_text())["order"]
        return order
    others = [p for p in study_dir.glob("*/study.json")]
    from itertools import permutations

    orders = list(permutations(schemes))
    order = list(orders[len(others) % len(orders)])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"participant": participant, "order": order}, indent=2))
    return order


def check_task_name(task: str) -> str:
    canonical_task(task)
    return task
