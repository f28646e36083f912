"""What a user can cause: the one exception the command lines print as one line.

The library raises `UsageError` (a ValueError) for a bad value, option, file or combination a
user gave; `cli.entry` turns it, and OSError, into `PROG: error: MESSAGE` and exit status 2.
Any other exception is a bug and keeps its traceback. Messages name the library's parameters,
not a command line's flags; `message` writes any of them as the one line a user reads.
"""

from __future__ import annotations


class UsageError(ValueError):
    """A bad input the caller can correct (its message says which and how)."""


def validate_fields(owner: str, validate) -> None:
    """Run `validate()`; a TypeError or ValueError it raises that is not a UsageError (a field
    of another type, as a hand-edited config.json holds) becomes one naming `owner`."""
    try:
        validate()
    except UsageError:
        raise
    except (TypeError, ValueError) as e:
        raise UsageError(f"{owner}: a field has the wrong type ({e})") from None


def shown_path(path, limit: int = 120) -> str:
    """`path` as text, its middle cut out if longer than `limit` characters."""
    text = str(path)
    if len(text) <= limit:
        return text
    return f"{text[: limit // 2]}...{text[-(limit // 2 - 3) :]} ({len(text):,} characters)"


def message(error) -> str:
    """One line for an exception or a message: OS errors name their file (shortened)."""
    if isinstance(error, OSError) and error.strerror:
        files = (error.filename, error.filename2)
        where = " -> ".join(shown_path(f) for f in files if f is not None)
        error = f"{where}: {error.strerror}" if where else error.strerror
    return " ".join(str(error).split()) or type(error).__name__
