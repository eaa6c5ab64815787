"""Progress of long work: a tqdm bar on a terminal, plain dated lines in a log."""

from __future__ import annotations

import sys
import threading
import time as _time

__all__ = ["Progress", "Heartbeat"]


class Progress:
    """Counts finished items; a bar with rate and ETA on a terminal, else a line every *every* seconds.

    Parameters
    ----------
    total : int
        Items in all.
    initial : int
        Items already done (a resumed run).
    bar : bool, optional
        Force the bar on or off (default: when *stream* is a terminal).
    stream : file
        Where progress goes.
    unit : str
        What an item is.
    every : float
        Seconds between plain lines.
    enabled : bool
        False: nothing at all.
    """

    def __init__(self, total: int, initial: int = 0, bar: bool | None = None, stream=None,
                 unit: str = "scene", every: float = 10.0, enabled: bool = True):
        self.enabled = enabled
        self.stream = stream or sys.stderr
        self.total, self.done, self.unit, self.every = total, initial, unit, every
        self._start = self._last = _time.monotonic()
        self._first = initial
        tty = getattr(self.stream, "isatty", lambda: False)()
        self._bar = None
        if enabled and (tty if bar is None else bar) and total > 0:
            from tqdm import tqdm
            self._bar = tqdm(total=total, initial=initial, unit=unit, file=self.stream, smoothing=0.05,
                             mininterval=0.5, dynamic_ncols=True)

    def update(self, count: int) -> None:
        """Add *count* finished items.

        Parameters
        ----------
        count : int
            Items just finished.
        """
        self.done += count
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(count)
            return
        now = _time.monotonic()
        if now - self._last >= self.every:
            self._last = now
            print(self.line(), file=self.stream, flush=True)

    def line(self) -> str:
        """Done, rate and time left, in one line."""
        elapsed = _time.monotonic() - self._start
        rate = (self.done - self._first) / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        share = 100.0 * self.done / self.total if self.total else 100.0
        eta = f"{left / 60:.1f} min left" if left == left else "time left unknown"
        speed = f"{rate:,.0f}" if rate >= 10 else f"{rate:.2g}"     # a slow unit is not "0 per second"
        return f"{self.done:,} of {self.total:,} {self.unit}s ({share:.1f}%), {speed} {self.unit}s/s, {eta}"

    def close(self) -> None:
        """End the bar (a plain log gets a last line)."""
        if self._bar is not None:
            self._bar.close()
        elif self.enabled and self.done > self._first:
            print(self.line(), file=self.stream, flush=True)


class Heartbeat:
    """Lines on a long wait: silent for *quiet* seconds, then one line every *every* seconds until it ends.

    Used as the ``progress`` hook of :func:`~analogy.study.comparison.compare`: it is
    called with a solver's name as it starts and with ``None`` when it ends. A run shorter
    than *quiet* prints nothing; a longer one says what runs and for how long, and how
    long it took.

    Parameters
    ----------
    stream : file
        Where the lines go (default stderr).
    quiet : float
        Seconds before the first line.
    every : float
        Seconds between lines.
    """

    def __init__(self, stream=None, quiet: float = 3.0, every: float = 15.0):
        self.stream = stream or sys.stderr
        self.quiet, self.every = quiet, every
        self._stop: threading.Event | None = None
        self._thread: threading.Thread | None = None

    def __call__(self, what: str | None) -> None:
        self._end()
        if what is not None:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._beat, args=(what, self._stop), daemon=True)
            self._thread.start()

    def _beat(self, what: str, stop: threading.Event) -> None:
        start = _time.monotonic()
        wait, spoke = self.quiet, False
        while not stop.wait(wait):
            print(f"analogy: {what} running, {_time.monotonic() - start:.0f} s so far", file=self.stream, flush=True)
            wait, spoke = self.every, True
        if spoke:
            print(f"analogy: {what} finished in {_time.monotonic() - start:.1f} s", file=self.stream, flush=True)

    def _end(self) -> None:
        if self._stop is not None:
            self._stop.set()
            self._thread.join()
            self._stop = self._thread = None
