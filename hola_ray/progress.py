"""Progress of long work: a tqdm bar on a terminal, plain lines in a log file.

tqdm redraws its bar with carriage returns, which a log file keeps (76 KB for 389 lines
of one run). Without a terminal on stderr, `progress` prints a plain line at most every
`PlainProgress.interval_s` seconds and one at the end instead.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from tqdm.auto import tqdm


def progress(total: int, desc: str, unit: str, enabled: bool = True):
    """A progress bar with tqdm's `update`, `set_postfix` and context manager."""
    if not enabled:
        return tqdm(total=total, disable=True)
    if sys.stderr.isatty():
        return tqdm(total=total, desc=desc, unit=unit)
    return PlainProgress(total, desc, unit)


class PlainProgress:
    """tqdm's interface as plain lines on stderr: `desc: n / total unit (p %), postfix`."""

    interval_s = 10.0

    def __init__(self, total: int, desc: str, unit: str) -> None:
        self.total, self.desc, self.unit = total, desc, unit
        self.n = 0
        self.postfix = ""
        self._start = self._last = time.monotonic()

    def update(self, k: int = 1) -> None:
        self.n += k
        if time.monotonic() - self._last >= self.interval_s:
            self._say()

    def set_postfix(self, **values: Any) -> None:
        self.postfix = ", ".join(f"{k} {v}" for k, v in values.items())

    def close(self) -> None:
        self._say()

    def _say(self) -> None:
        self._last = time.monotonic()
        share = f" ({self.n / self.total:.0%})" if self.total else ""
        line = f"{self.desc}: {self.n:,} / {self.total:,} {self.unit}{share}"
        line += f", {time.monotonic() - self._start:.0f} s"
        print(line + (f"; {self.postfix}" if self.postfix else ""), file=sys.stderr, flush=True)

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
