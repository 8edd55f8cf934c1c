"""Progress on stderr: a bar on a terminal, one plain line per finished step elsewhere.

On a terminal the bar is ``tqdm``'s (the ``progress`` extra) or, without it, a status line
at most once a second.  Written to a file or a pipe (a log, CI, ``2>&1 | tee``) there are no
carriage-return updates: one line per finished step, so a log reads top to bottom.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["ProgressBar"]


class ProgressBar:
    """Progress of ``total`` steps on stderr (see the module notes).

    Parameters
    ----------
    total : int
        Number of steps.
    description : str
        Label shown before the bar.
    unit : str
        What a step is (``"run"``, ``"FE"``).
    delay : float
        Seconds before a terminal bar appears (so work shorter than that shows none).
    stream : file, optional
        Where to write (default ``sys.stderr``); its ``isatty()`` chooses the bar or lines.
    """

    def __init__(
        self,
        total: int,
        description: str = "",
        *,
        unit: str = "run",
        delay: float = 0.0,
        stream: TextIO | None = None,
    ) -> None:
        self.total = total
        self.count = 0
        self.description = description
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self._last = 0.0
        self._t0 = time.perf_counter()
        self._delay = float(delay)
        isatty = getattr(self.stream, "isatty", None)
        self.terminal = bool(isatty and isatty())
        self._bar = None
        if self.terminal:
            try:
                from tqdm import tqdm
            except ImportError:
                pass
            else:
                self._bar = tqdm(
                    total=total, desc=description, unit=unit, leave=True, file=self.stream,
                    delay=self._delay,
                )

    def update(self, n: int = 1, status: str = "") -> None:
        """Advance by ``n`` steps.

        Parameters
        ----------
        n : int, optional
            Number of steps completed (default 1).
        status : str, optional
            A short note on the latest step, shown after the count.
        """
        self.count += n
        if self._bar is not None:
            self._bar.update(n)
            if status:
                self._bar.set_postfix_str(status, refresh=False)
            return
        now = time.perf_counter()
        elapsed = now - self._t0
        if self.terminal:  # no tqdm: a status line at most once a second, and at the end
            due = now - self._last >= 1.0 and elapsed >= self._delay
            if not (due or self.count == self.total):
                return
            self._last = now
        print(
            f"{self.description}: {self.count}/{self.total} {self.unit} ({elapsed:.0f} s)"
            + (f" {status}" if status else ""),
            file=self.stream,
            flush=True,
        )

    def close(self) -> None:
        """Finish the bar."""
        if self._bar is not None:
            self._bar.close()
