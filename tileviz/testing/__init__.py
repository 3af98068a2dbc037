"""What the tests (``tests/``) and the benches (``bench/``) share: one importable package.

Nothing in the product imports this package. Its modules:

- :mod:`~tileviz.testing.floorgen`: tiled-floor views rendered independently of
  ``tileviz.sim.camera`` (nine floor families, five corruptions);
- :mod:`~tileviz.testing.views`: one view of the vision study drawn from a seed and read by the
  robust extractor (the study, a cable along a grout line, a short motion blur);
- :mod:`~tileviz.testing.exact_truth`: the truth in exact arithmetic (mpmath);
- :mod:`~tileviz.testing.adversary`: runs that respect every declared bound at their nastiest;
- :mod:`~tileviz.testing.drives`: synthetic drives with sensors within their bounds;
- :mod:`~tileviz.testing.golden`: the recorded localizer sequences (``tests/data``) and their
  bit-for-bit comparison;
- :mod:`~tileviz.testing.fault_dataset`: a dataset with a slip, a kidnap and a dropout;
- :mod:`~tileviz.testing.wsclient`, :mod:`~tileviz.testing.churn`: a viser websocket client and
  websocket clients that connect and leave again and again;
- :mod:`~tileviz.testing.browser`: headless chromium's options and CPU accounting;
- :mod:`~tileviz.testing.timing`: the benches' clock and shared options;
- :mod:`~tileviz.testing.figures`: the blocks the benches write into ``docs/figures.md``;
- :mod:`~tileviz.testing.fuzzing`: every reader a user's file reaches, fuzzed (hypothesis and
  mutation cases run in worker processes, their outcomes classified);
- :mod:`~tileviz.testing.extras`: the command line run as if the ``ros`` extra were missing;
- :mod:`~tileviz.testing.codac_oracle_worker`: codac's side of the oracle (a subprocess only).

Some need packages of the ``test`` extra (``pip install -e '.[test]'``); those are imported where
they are used, and a missing one is named in one line (:func:`missing`).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["REPO", "missing"]

REPO = Path(__file__).resolve().parents[2]
"""The checkout this package is imported from (its ``serve.py``, ``tests/data``, ``docs/``)."""


def missing(package: str, what: str) -> str:
    """The one-line error for ``what`` when ``package`` cannot be imported."""
    return (f"{package} is missing ({what} needs it; it comes with tileviz's test extra: "
            f"pip install -e '.[test]')")
