"""A small progress bar on stderr (silent unless stderr is a terminal)."""

from __future__ import annotations

import sys
import time
from typing import Any, Optional, TextIO


class Progress:
    """``with Progress(total, "filtering") as p: ... p.update(k)``.

    Draws ``label [#####.....] 40% 2.1 s`` on one line of ``stream``
    (default stderr), only when it is a TTY, at most every 0.1 s, and
    clears the line at the end. ``enabled=False`` silences it.
    """

    def __init__(self, total: int, label: str = "", stream: Optional[TextIO] = None, enabled: Optional[bool] = None, width: int = 30):
        self.total = max(int(total), 1)
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.width = width
        self.done = 0
        self._t0 = time.perf_counter()
        self._last = -1.0

    def __enter__(self) -> "Progress":
        self._t0 = time.perf_counter()
        self._draw(force=True)
        return self

    def update(self, n: int = 1) -> None:
        self.done = min(self.total, self.done + int(n))
        self._draw(force=self.done == self.total)

    def _draw(self, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        frac = self.done / self.total
        fill = int(round(frac * self.width))
        bar = "#" * fill + "." * (self.width - fill)
        self.stream.write(f"\r{self.label} [{bar}] {frac:4.0%} {now - self._t0:5.1f} s")
        self.stream.flush()

    def __exit__(self, *exc: Any) -> None:
        if self.enabled:
            self.stream.write("\r" + " " * (len(self.label) + self.width + 20) + "\r")
            self.stream.flush()
