"""What every command line of the project shares: a bad input is one line and exit code 2."""

from __future__ import annotations

import argparse
import sys


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr (`prog: error: …`) and exit code 2,
    without the usage block (`--help` still prints it)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def fail(message: str) -> int:
    """Print `error: message` as one line on stderr; the exit code 2 to return."""
    print(f"error: {' '.join(str(message).split())}", file=sys.stderr)
    return 2
