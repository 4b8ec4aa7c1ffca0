"""Progress of `stereodyn run`: on a terminal, a bar with an ETA over a sweep; off a terminal (a log, CI), one line
per phase and a heartbeat line at least every HEARTBEAT_S (phase, count done of total where the phase counts, elapsed,
ETA), so a log never goes quiet for minutes. Silent when disabled (--quiet).

The ETA weighs runs by their cost estimate (estimated seconds, harness.run.pool.cost), since the sweep starts the
longest runs first and a count-based estimate would be far too pessimistic early on.
"""
from __future__ import annotations

import shutil
import sys
import threading
import time
from typing import Callable, TextIO

REFRESH_S = 0.1  # redraw at most this often, except for the last run
# Off a terminal, a line at least this often (issue 32 promises 30 s; 20 leaves room for a thread woken late on a
# loaded machine: the heartbeat thread checks every HEARTBEAT_POLL_S)
HEARTBEAT_S = 20.0
HEARTBEAT_POLL_S = 1.0


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class ProgressBar:
    """Drawn on one line of `stream` with carriage returns; the sweep calls phase(), start(), advance(), close()."""

    def __init__(self, stream: TextIO | None = None, enabled: bool | None = None, width: int | None = None,
                 clock: Callable[[], float] = time.monotonic, heartbeat: bool = True):
        self.stream = sys.stderr if stream is None else stream
        is_tty = getattr(self.stream, "isatty", lambda: False)()
        self.enabled = is_tty if enabled is None else enabled and is_tty
        # Off a terminal (a log, CI): no bar, but one plain line per phase of the run (stage()), as on a terminal,
        # and the heartbeat between them
        self.plain = (enabled is None or enabled) and not is_tty
        self.width = width
        self.clock = clock
        self.total = self.done = 0
        self.total_cost = self.done_cost = 0.0
        self.started = self._last_draw = 0.0
        self._drawn = False
        self.note = ""
        self.phase_name = ""
        self.begun = self.phase_begun = self._last_line = clock()
        self._lock = threading.Lock()  # the heartbeat thread and the caller write lines
        self._stop = threading.Event()
        self._thread = None
        if self.plain and heartbeat:
            self._thread = threading.Thread(target=self._beat, name="stereodyn-heartbeat", daemon=True)
            self._thread.start()

    def elapsed(self) -> float:
        """Seconds since the progress began (the command's start)."""
        return self.clock() - self.begun

    def finish(self) -> float:
        """Stop the heartbeat; the elapsed seconds."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2 * HEARTBEAT_POLL_S)
        return self.elapsed()

    def _beat(self) -> None:
        while not self._stop.wait(HEARTBEAT_POLL_S):
            self.heartbeat()

    def heartbeat(self) -> None:
        """Off a terminal: a line when none was written for HEARTBEAT_S (the thread calls it; tests with a fake
        clock call it directly)."""
        if not self.plain or self.clock() - self._last_line < HEARTBEAT_S:
            return
        now = self.clock()
        counted = ""
        if self.total:
            fraction = min(1.0, self.done_cost / self.total_cost)
            spent = now - self.started
            eta = _clock(spent * (1 - fraction) / fraction) if fraction > 0 else "?"
            counted = f", {self.done}/{self.total} runs, ETA {eta}"
        self._write(f"stereodyn: ... {self.phase_name or 'starting'}{counted}; {_clock(now - self.phase_begun)} in "
                    f"this phase, {_clock(now - self.begun)} in all\n")

    def _write(self, text: str) -> None:
        with self._lock:
            self.stream.write(text)
            self.stream.flush()
            self._last_line = self.clock()

    def phase(self, text: str) -> None:
        """A step before the runs (the truth of each case)."""
        self._draw(text, force=True)

    def stage(self, text: str) -> None:
        """A phase of the whole run (truths, runs, timing, ladders, report): one line, on a terminal or not."""
        if not (self.plain or self.enabled):
            return
        if self._drawn:  # a finished phase's bar stays on its line
            self.stream.write("\n")
            self._drawn = False
        self.phase_name, self.phase_begun = text, self.clock()
        self.total = self.done = 0  # a phase counts its runs only where it calls start()
        self.total_cost = self.done_cost = 0.0
        self._write(f"stereodyn: {text}\n")

    def start(self, total: int, total_cost: float, resumed: int = 0) -> None:
        self.total, self.total_cost, self.done, self.done_cost = total, max(total_cost, 1e-300), 0, 0.0
        self.started = self.clock()
        self.note = f" ({resumed} resumed)" if resumed else ""
        self._draw("", force=True)

    def advance(self, label: str, cost: float, status: str) -> None:
        self.done += 1
        self.done_cost += cost
        self._draw(f"{label}: {status}", force=self.done == self.total)

    def close(self) -> None:
        if self.enabled and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
        self._drawn = False

    def line(self, last: str) -> str:
        """The bar's text: count, bar, percentage, elapsed, ETA, the last event."""
        if not self.total:
            return last
        fraction = min(1.0, self.done_cost / self.total_cost)
        elapsed = self.clock() - self.started
        eta = _clock(elapsed * (1 - fraction) / fraction) if fraction > 0 else "?"
        cells = 20
        filled = int(round(cells * fraction))
        return (f"{self.done}/{self.total}{self.note} [{'#' * filled}{'.' * (cells - filled)}] {100 * fraction:3.0f}% "
                f"{_clock(elapsed)} ETA {eta}  {last}")

    def _draw(self, last: str, force: bool = False) -> None:
        if not self.enabled:
            return
        now = self.clock()
        if not force and now - self._last_draw < REFRESH_S:
            return
        self._last_draw = now
        width = self.width or shutil.get_terminal_size((100, 20)).columns
        text = self.line(last)[:max(10, width - 1)]
        self.stream.write("\r" + text.ljust(width - 1))
        self.stream.flush()
        self._drawn = True

