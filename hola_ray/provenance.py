"""Where a file came from: the repository commit the code ran at."""

from __future__ import annotations

import functools
import subprocess

from hola_ray.homes import ROOT


@functools.cache
def commit_id() -> str:
    """The repository's HEAD, with "-dirty" when tracked files other than the pools' own
    (which a pool build writes) differ from it; "unknown" outside a git checkout. Read once
    per process."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!pools"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")
