"""Settings shared by every test module.

Hypothesis runs the same examples on every machine and every run (``derandomize``: CI stays
stable) and never fails a test for being slow (no deadline, no too-slow health check): the
machine a test runs on may be loaded, and time is not what these tests assert."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

settings.register_profile(
    "tileviz",
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("tileviz")
