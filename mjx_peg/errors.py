"""What a user can cause: the one exception the command lines print as one line.

The library raises `UsageError` (a ValueError) for a bad value, option, file or combination a
user gave; `cli.entry` turns it, and OSError, into `PROG: error: MESSAGE` and exit status 2.
Any other exception is a bug and keeps its traceback. Messages name the library's parameters,
not a command line's flags.
"""

from __future__ import annotations


class UsageError(ValueError):
    """A bad input the caller can correct (its message says which and how)."""
