"""engines/interrupt.py: a stop request reaches engine calls wherever they run."""

import pytest

from mjx_peg.engines import interrupt


def test_a_request_stands_until_cleared():
    interrupt.clear()
    assert not interrupt.requested()
    interrupt.check()  # nothing requested: returns
    interrupt.request()
    try:
        assert interrupt.requested()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()  # still standing: every running call stops
    finally:
        interrupt.clear()
    assert not interrupt.requested()
