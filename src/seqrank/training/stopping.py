"""Ctrl-C and SIGTERM end a command cleanly: checkpoint and label export first.

The first SIGINT or SIGTERM calls the command's `on_stop` (a run then stops at its next
episode end with a checkpoint; the labelling page stops waiting and writes its export);
a second one raises KeyboardInterrupt at once. The command then exits with 128 + the
signal's number (130 after Ctrl-C, 143 after SIGTERM), as shells expect.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignal:
    """Which signal asked the command to stop, if one did."""

    def __init__(self) -> None:
        self.signum: int | None = None

    @property
    def received(self) -> bool:
        return self.signum is not None

    def exit_code(self, default: int = 130) -> int:
        return 128 + self.signum if self.signum is not None else default


Handler = Callable[[int, FrameType | None], None]


@contextlib.contextmanager
def _handling(handle: Handler) -> Iterator[None]:
    """`handle` answers SIGINT and SIGTERM within the block; the old handlers come back."""
    previous = {number: signal.signal(number, handle) for number in SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def stop_then_interrupt(on_first: Callable[[int], None]) -> Handler:
    """A signal handler: the first signal calls `on_first(signum)`, later ones raise
    KeyboardInterrupt (the rule of every command, and of a sweep's worker processes)."""
    received = False

    def handle(signum: int, frame: FrameType | None) -> None:
        nonlocal received
        if received:
            raise KeyboardInterrupt
        received = True
        on_first(signum)

    return handle


@contextlib.contextmanager
def stop_on_signals(
    on_stop: Callable[[], None], say: Callable[[str], None]
) -> Iterator[StopSignal]:
    """Within the block, the first SIGINT/SIGTERM calls `on_stop`, a second interrupts."""
    stop = StopSignal()
    if threading.current_thread() is not threading.main_thread():
        yield stop  # signals reach the main thread only
        return

    def first(signum: int) -> None:
        stop.signum = signum
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        say(f"{name}: stopping cleanly (saving first; Ctrl-C again stops at once)")
        on_stop()

    with _handling(stop_then_interrupt(first)):
        yield stop


@contextlib.contextmanager
def interrupt_on_signals(on_signal: Callable[[], None]) -> Iterator[StopSignal]:
    """Within the block, every SIGINT/SIGTERM calls `on_signal` and raises
    KeyboardInterrupt; for a command with nothing to save (dataset make: `on_signal` does
    nothing), or whose work runs in other processes that `on_signal` tells to stop (the
    sweep), so that a signal sent to the command alone reaches them."""
    stop = StopSignal()
    if threading.current_thread() is not threading.main_thread():
        yield stop  # signals reach the main thread only
        return

    def handle(signum: int, frame: FrameType | None) -> None:
        if not stop.received:
            stop.signum = signum
        on_signal()
        raise KeyboardInterrupt

    with _handling(handle):
        yield stop
