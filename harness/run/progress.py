"""A progress bar with an ETA over a sweep, on a terminal only: silent when the stream is not a TTY, or when disabled.

The ETA weighs runs by their cost estimate (estimated seconds, harness.run.sweep._cost), since the sweep starts the
longest runs first and a count-based estimate would be far too pessimistic early on.
"""
from __future__ import annotations

import shutil
import sys
import time
from typing import TextIO

REFRESH_S = 0.1  # redraw at most this often, except for the last run


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class ProgressBar:
    """Drawn on one line of `stream` with carriage returns; the sweep calls phase(), start(), advance(), close()."""

    def __init__(self, stream: TextIO | None = None, enabled: bool | None = None, width: int | None = None):
        self.stream = sys.stderr if stream is None else stream
        is_tty = getattr(self.stream, "isatty", lambda: False)()
        self.enabled = is_tty if enabled is None else enabled and is_tty
        # Off a terminal (a log, CI): no bar, but one plain line per phase of the run (stage()), as on a terminal.
        self.plain = (enabled is None or enabled) and not is_tty
        self.width = width
        self.total = self.done = 0
        self.total_cost = self.done_cost = 0.0
        self.started = self._last_draw = 0.0
        self._drawn = False
        self.note = ""

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
        self.stream.write(f"stereodyn: {text}\n")
        self.stream.flush()

    def start(self, total: int, total_cost: float, resumed: int = 0) -> None:
        self.total, self.total_cost, self.done, self.done_cost = total, max(total_cost, 1e-300), 0, 0.0
        self.started = time.monotonic()
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
        elapsed = time.monotonic() - self.started
        eta = _clock(elapsed * (1 - fraction) / fraction) if fraction > 0 else "?"
        cells = 20
        filled = int(round(cells * fraction))
        return (f"{self.done}/{self.total}{self.note} [{'#' * filled}{'.' * (cells - filled)}] {100 * fraction:3.0f}% "
                f"{_clock(elapsed)} ETA {eta}  {last}")

    def _draw(self, last: str, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last_draw < REFRESH_S:
            return
        self._last_draw = now
        width = self.width or shutil.get_terminal_size((100, 20)).columns
        text = self.line(last)[:max(10, width - 1)]
        self.stream.write("\r" + text.ljust(width - 1))
        self.stream.flush()
        self._drawn = True

