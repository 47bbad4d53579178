"""Ctrl-C (and SIGTERM, which the CLI turns into it) held off while files that belong
together are finished: a `Deferral` records the signal instead of raising it, so that an
interrupted `gyro-fmu run` never leaves complete results without the summary.json that
describes them. A second signal while held raises at once (the user insists; `gyro-fmu
report` then refuses results without their summary). Only in the main thread, and only
for a signal whose handler is Python's default (a background job's ignored SIGINT stays
ignored)."""

from __future__ import annotations

import signal
import sys
import threading


def hold_signals(handler) -> dict[int, object]:
    """Install handler for SIGINT and SIGTERM where Python handles them (SIGINT at Python's
    default, SIGTERM with a Python handler such as the CLI's), in the main thread only;
    returns the handlers replaced, for `restore_signals`."""
    replaced: dict[int, object] = {}
    if threading.current_thread() is not threading.main_thread():
        return replaced
    for signum in (signal.SIGINT, signal.SIGTERM):
        current = signal.getsignal(signum)
        if (current is signal.default_int_handler if signum == signal.SIGINT
                else callable(current)):
            replaced[signum] = current
            signal.signal(signum, handler)
    return replaced


def restore_signals(replaced: dict[int, object]) -> None:
    for signum, handler in replaced.items():
        signal.signal(signum, handler)  # type: ignore[arg-type]
    replaced.clear()


class Deferral:
    """start() holds SIGINT/SIGTERM, stop() restores their handlers; `caught` tells whether
    one came in between (the caller then raises KeyboardInterrupt when done)."""

    def __init__(self, note: str = "") -> None:
        self.note = note
        self.caught: list[int] = []
        self._replaced: dict[int, object] = {}

    def _hold(self, signum: int, frame: object) -> None:
        if self.caught:
            raise KeyboardInterrupt("interrupted again while finishing the outputs")
        self.caught.append(signum)
        if self.note:
            print(self.note, file=sys.stderr, flush=True)

    def start(self) -> Deferral:
        self._replaced = hold_signals(self._hold)
        return self

    def stop(self) -> None:
        restore_signals(self._replaced)
