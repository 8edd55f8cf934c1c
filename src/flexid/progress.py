"""Progress bars for long work: tqdm when it is installed, a plain stderr line otherwise."""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar"]


class ProgressBar:
    """A progress bar on stderr.

    Uses ``tqdm`` (the ``progress`` extra) when available; otherwise prints a short status
    line at most once a second, so logs stay readable when stderr is not a terminal.

    Parameters
    ----------
    total : int
        Number of steps.
    description : str
        Label shown before the bar.
    """

    def __init__(self, total: int, description: str = "") -> None:
        self.total = total
        self.count = 0
        self.description = description
        self._last = 0.0
        self._t0 = time.perf_counter()
        try:
            from tqdm import tqdm
        except ImportError:
            self._bar = None
        else:
            self._bar = tqdm(total=total, desc=description, unit="run", leave=True, file=sys.stderr)

    def update(self, n: int = 1, status: str = "") -> None:
        """Advance the bar.

        Without tqdm a line goes to stderr at most once a second, and at the last step.

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
        if now - self._last >= 1.0 or self.count == self.total:
            self._last = now
            elapsed = now - self._t0
            print(
                f"{self.description}: {self.count}/{self.total} ({elapsed:.0f} s) {status}",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        """Finish the bar."""
        if self._bar is not None:
            self._bar.close()
