"""What the three `seqrank label` modes share: the page's options, the server, the end."""

from __future__ import annotations

import argparse
import contextlib
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from seqrank.cli.options import frame_size, int_between, number_between, port_number
from seqrank.errors import UsageError
from seqrank.labelling import CLIP_SIZE

SERVER_HELP = "labelling page options"
PLAYBACKS = ("side-by-side", "one-after-another")
MAX_COUNTDOWN = 3600.0  # seconds per question


def allowed_host(text: str) -> str:
    """A name or address a browser can send as the Host header: letters, digits, '-' and
    '.' (an IPv6 address in brackets or bare), no port."""
    import ipaddress
    import re

    name = text.strip().removeprefix("[").removesuffix("]")
    try:
        return str(ipaddress.ip_address(name))
    except ValueError:
        pass
    if re.fullmatch(r"(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?\.?)+", name):
        return name.rstrip(".").lower()
    raise argparse.ArgumentTypeError(
        f"{text!r} is not a host name or address: give a name of letters, digits, '-' and "
        "'.' (e.g. labels.example.org) or an IP address, without a port"
    )


def server_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(SERVER_HELP)
    group.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (127.0.0.1); any other needs a token, made if not given",
    )
    group.add_argument("--port", type=port_number, default=8765, help="(8765; 0: a free port)")
    group.add_argument(
        "--token", help="access token the page must carry (16+ characters beyond 127.0.0.1)"
    )
    group.add_argument(
        "--allow-host",
        action="append",
        type=allowed_host,
        default=[],
        metavar="NAME",
        help="another name or address the page is opened by (e.g. a public IP in front of "
        "this machine); others are refused (DNS-rebinding defence)",
    )
    group.add_argument(
        "--countdown", type=float, default=3.0, help="seconds per question (3, as D.7; 0: none)"
    )
    group.add_argument("--annotator", default="anonymous", help="stored with every answer")
    group.add_argument("--fps", type=int_between(1, 120), default=30, help="clip frame rate (30)")
    group.add_argument(
        "--size", type=frame_size, default=CLIP_SIZE, help=f"clip width and height ({CLIP_SIZE})"
    )
    group.add_argument(
        "--playback",
        choices=PLAYBACKS,
        default=PLAYBACKS[0],
        help="the two clips loop side by side, or play one after the other in turn (as the "
        "paper's study instructions describe)",
    )
    group.add_argument(
        "--keep-serving", action="store_true", help="keep the page up after the last answer"
    )
    group.add_argument(
        "--reassign-after",
        type=number_between(1.0, 86_400.0),
        default=60.0,
        metavar="SECONDS",
        help="a team (--annotators): a question unanswered this long is handed to the others (60)",
    )


def page_options(args: argparse.Namespace) -> Any:
    from seqrank.labelling.access import page_token
    from seqrank.labelling.app import ServerOptions

    if not 0 <= args.countdown <= MAX_COUNTDOWN:  # nan and inf too
        raise UsageError(
            f"--countdown {args.countdown}: must be 0 (none) or more seconds, at most "
            f"{MAX_COUNTDOWN}"
        )
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
        playback=args.playback,
    )


def check_address(host: str, port: int) -> None:
    """UsageError when the page could not listen on host:port (before anything is made)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as error:
            reason = error.strerror or str(error)
            raise UsageError(
                f"--host {host} --port {port}: cannot listen there ({reason}); choose another "
                "--port (0 picks a free one) or an address of this machine"
            ) from None


def serve(hub: Any, args: argparse.Namespace, say: Any) -> Any:
    from seqrank.labelling.app import PageServer

    server = PageServer(hub, page_options(args))
    server.start()
    for line in server.announce():
        say(line)
    return server


@contextlib.contextmanager
def page_served(hub: Any, directory: Path, args: argparse.Namespace, say: Any) -> Iterator[Any]:
    """The page served within the block, then `finish` on every way out, an error's too:
    the server and clip threads must be ended (the GL context freed on its own thread)
    before the interpreter exits, or it crashes at exit (a segmentation fault, exit 139)."""
    server = serve(hub, args, say)
    try:
        yield server
    except BaseException:
        hub.stop.set()  # an error ends the page at once: no pause, no --keep-serving
        raise
    finally:
        finish(hub, server, directory, args, say)


def finish(hub: Any, server: Any, directory: Path, args: argparse.Namespace, say: Any) -> None:
    """Keep serving if asked (until Ctrl-C), stop the page, write the label export."""
    from seqrank.labelling.app import close_hub

    try:
        if args.keep_serving and not hub.stop.is_set():
            say("all done; the page stays up until Ctrl-C")
            while not hub.stop.is_set():  # the first Ctrl-C or SIGTERM sets it
                time.sleep(0.2)
        elif not hub.stop.is_set():
            time.sleep(1.5)  # let the page show that it is done
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        close_hub(hub, directory, say)


def human_trainer(hub: Any, run_name: str, wait: bool, say: Any) -> Any:
    from seqrank.labelling.app import record_task, training_progress
    from seqrank.training.trainer import Trainer

    def build(config: Any, run: Any) -> Any:
        trainer = Trainer(
            config,
            run,
            source=hub.source(run_name, config.seed),
            wait_for_feedback=wait,
        )
        env = trainer.env
        record_task(hub.db, config.task, env.obs_dim, env.act_dim, config.segment_length)
        trainer.progress = training_progress(hub, config, say)
        hub.state.plan(config.sessions)
        return trainer

    return build


def human_overrides(args: argparse.Namespace) -> None:
    if hasattr(args, "resume"):
        return
    if getattr(args, "teacher", "human") != "human":
        raise ValueError(f"--teacher {args.teacher}: the labelling page's teacher is the person")
    args.teacher, args.record_states = "human", 1
