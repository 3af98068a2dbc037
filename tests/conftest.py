"""Settings shared by every test module.

Hypothesis runs the same examples on every machine and every run (``derandomize``: CI stays
stable) and never fails a test for being slow (no deadline, no too-slow health check): the
machine a test runs on may be loaded, and time is not what these tests assert. And no test may
leave the process rounding upward."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "tileviz",
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("tileviz")


@pytest.fixture(autouse=True)
def _still_rounding_to_nearest() -> Iterator[None]:
    """Every test leaves the process rounding to nearest: ``import codac`` switches it to upward
    rounding for good, which would silently change every later test's floats."""
    yield
    assert 1.0 + 2.0**-53 == 1.0, "this test left the process rounding upward (codac imported?)"
