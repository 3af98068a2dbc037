"""Command-line helpers shared by every entry point."""

from __future__ import annotations

import time

import pytest

from tileviz.cliutil import notice_if_slow


def test_notice_if_slow_speaks_only_when_the_block_outlasts_it(
        capsys: pytest.CaptureFixture[str]) -> None:
    """A slow start says why on standard error; a quick one says nothing."""
    with notice_if_slow("still starting: compiling", after=0.05):
        deadline = time.monotonic() + 20.0
        seen = ""
        while "compiling" not in seen and time.monotonic() < deadline:
            time.sleep(0.02)
            seen += capsys.readouterr().err
    assert seen.strip() == "still starting: compiling"
    with notice_if_slow("never shown", after=30.0):
        pass
    time.sleep(0.1)
    assert capsys.readouterr().err == ""


def test_a_notice_cancelled_by_the_block_is_never_shown(
        capsys: pytest.CaptureFixture[str]) -> None:
    """The block's first result cancels the notice (``extract``, ``replay``): a slow run after
    a quick start says nothing."""
    with notice_if_slow("never shown", after=0.05) as slow:
        slow.cancel()
        time.sleep(0.2)
    assert capsys.readouterr().err == ""
