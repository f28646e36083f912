"""errors.py: a user's mistake is a ValueError; any exception or message becomes one line, an
OS error naming its file."""

from __future__ import annotations

import errno

import pytest

from mjx_peg.errors import UsageError, message


def test_a_usage_error_is_a_value_error():
    with pytest.raises(ValueError, match="--trials must be positive"):
        raise UsageError("--trials must be positive")


@pytest.mark.parametrize(
    "error, line",
    [
        ("two\n  lines   here ", "two lines here"),
        (ValueError("bad\tvalue\n"), "bad value"),
        (ValueError(""), "ValueError"),
        (KeyError("obs_mean"), "'obs_mean'"),
        (FileNotFoundError(errno.ENOENT, "No such file or directory", "/runs/x/policy.npz"),
         "/runs/x/policy.npz: No such file or directory"),
        (OSError(errno.EXDEV, "Invalid cross-device link", "/a/run", None, "/b/run"),
         "/a/run -> /b/run: Invalid cross-device link"),
        (OSError(errno.ENOSPC, "No space left on device"), "No space left on device"),
        (OSError("a message without an errno"), "a message without an errno"),
    ],
)  # fmt: skip
def test_one_line_for_any_error(error, line):
    assert message(error) == line
