"""errors.py: a user's mistake is a ValueError; any exception or message becomes one line, an
OS error naming its file."""

from __future__ import annotations

import errno

import pytest

from mjx_peg.errors import UsageError, message, validate_fields


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


def test_validate_fields_names_the_owner_of_a_field_of_another_type():
    def bad_type():
        return 1.0 < "2"  # a TypeError, as a string where a number belongs raises

    def bad_value():
        raise UsageError("--trials must be positive")

    with pytest.raises(UsageError, match=r"^TrainConfig: a field has the wrong type \("):
        validate_fields("TrainConfig", bad_type)
    with pytest.raises(UsageError, match="^--trials must be positive$"):
        validate_fields("TrainConfig", bad_value)
    assert validate_fields("TrainConfig", lambda: None) is None
