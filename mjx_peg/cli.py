"""The command-line boundary every CLI shares: bad input is one line on stderr and exit status 2.

    parser = cli.Parser(prog="eval.py", description=...)   # argparse errors: one line, exit 2
    return cli.fail(PROG, exc)                             # a caught error: one line, returns 2

Imports nothing of the package, so a CLI can parse its arguments before importing MuJoCo or JAX.
"""

from __future__ import annotations

import argparse
import sys

EXIT_USAGE = 2  # bad input, as argparse
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT)
# What a user can cause (a bad value, an unreadable or unwritable path): one line, never a trace.
USER_ERRORS: tuple[type[BaseException], ...] = (ValueError, OSError)


class Parser(argparse.ArgumentParser):
    """argparse whose errors are one stderr line, `PROG: error: MESSAGE`, and exit status 2."""

    def error(self, message: str):
        raise SystemExit(fail(self.prog, message))


def fail(prog: str, message) -> int:
    """Print `PROG: error: MESSAGE` (one line) on stderr and return the usage exit status."""
    text = " ".join(str(message).split()) or type(message).__name__
    print(f"{prog}: error: {text}", file=sys.stderr)
    return EXIT_USAGE
