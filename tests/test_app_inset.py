"""The magnified inset: the sets around the truth at a scale that fits them, several disjoint
candidate boxes apart, the truth, and a scale bar."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tileviz.app.inset import BACKGROUND, nice_length, render_inset
from tileviz.app.scene import COLOURS
from tileviz.types import Box, BoxSet, Pose


def record(predicted: BoxSet, updated: BoxSet, truth: Pose | None, status: str = "contracted"):
    def inside() -> bool | None:
        return None if truth is None else updated.contains(truth.x, truth.y, truth.theta)

    return SimpleNamespace(index=0, t=0.0, predicted=predicted, updated=updated, truth=truth,
                           status=status, truth_inside=inside)


def near(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 40) -> np.ndarray:
    """Pixels within ``tol`` of colour ``rgb`` (a blend with the background counts)."""
    return (np.abs(img.astype(int) - np.array(rgb)).max(axis=2) <= tol)


def bluish(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (b > r + 40) & (b > g + 15)


def greenish(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (g > r + 25) & (g > b + 25)


def test_a_centimetre_set_fills_the_inset_with_truth_and_scale_bar():
    truth = Pose(2.3, -1.1, 0.4)
    pred = BoxSet((Box(2.290, 2.312, -1.109, -1.088, 0.39, 0.41),))
    upd = BoxSet((Box(2.294, 2.306, -1.105, -1.094, 0.395, 0.405),))
    img = render_inset(record(pred, upd, truth), tile_size=1.0, size=360)
    assert img.shape == (360, 360, 3) and img.dtype == np.uint8
    blue, green = bluish(img), greenish(img)
    # the 1.2 cm set spans a large part of the image (magnified), inside the prediction
    assert blue.sum() > 0.05 * 360 * 360 and green.sum() > 0.01 * 360 * 360
    rows, cols = np.nonzero(blue)
    assert 100 < cols.max() - cols.min() < 330
    # the truth (pink) is drawn at the centre
    pink = near(img, COLOURS["truth"], 30)
    assert pink[170:190, 170:190].any()
    # a scale bar: a dark horizontal line near the bottom left
    dark = (img.max(axis=2) < 80)[330:350, 10:200]
    assert dark.any(axis=0).sum() > 30


def test_disjoint_candidate_boxes_all_show_apart():
    truth = Pose(0.5, 0.5, 0.0)
    a = Box(0.495, 0.505, 0.495, 0.505, -0.01, 0.01)
    b = Box(0.545, 0.555, 0.495, 0.505, -0.01, 0.01)
    c = Box(0.495, 0.505, 0.445, 0.455, -0.01, 0.01)
    upd = BoxSet((a, b, c))
    pred = BoxSet((Box(0.49, 0.56, 0.44, 0.51, -0.02, 0.02),))
    img = render_inset(record(pred, upd, truth), tile_size=1.0)
    outline = near(img, COLOURS["boxes"], 25)
    # three separate outlined boxes: three clusters of blue columns/rows
    cols = np.flatnonzero(outline.any(axis=0))
    rows = np.flatnonzero(outline.any(axis=1))
    assert (np.diff(cols) > 5).sum() >= 1 and (np.diff(rows) > 5).sum() >= 1
    assert outline.sum() > 200


def test_without_truth_it_centres_on_the_set_and_an_empty_set_says_so():
    upd = BoxSet((Box(3.0, 3.01, 4.0, 4.01, 0.0, 0.01),))
    img = render_inset(record(upd, upd, None), tile_size=1.0, size=200)
    blue = near(img, COLOURS["boxes"], 25)
    rows, cols = np.nonzero(blue)
    assert abs(cols.mean() - 100) < 20 and abs(rows.mean() - 100) < 20
    empty = render_inset(record(BoxSet(()), BoxSet(()), None, "lost"), tile_size=1.0, size=200)
    assert (empty != np.array(BACKGROUND, np.uint8)).any()  # the words "no set to show"


@given(st.floats(1e-6, 1e6))
def test_nice_length_is_1_2_or_5_times_a_power_of_ten_and_not_above(most):
    v = nice_length(most)
    assert 0 < v <= most * (1 + 1e-12) and v > most / 10.0 * (1 - 1e-12) / 1.0 * 0.49
    mant = v / 10.0 ** math.floor(math.log10(v) + 1e-12)
    assert min(abs(mant - m) for m in (1.0, 2.0, 5.0)) < 1e-9


@pytest.mark.parametrize("metres", [0.004, 0.03, 2.0])
def test_the_scale_bar_stays_readable_at_any_zoom(metres):
    truth = Pose(0.0, 0.0, 1.0)
    h = metres / 2
    box = BoxSet((Box(-h, h, -h, h, 0.9, 1.1),))
    img = render_inset(record(box, box, truth), tile_size=1.0)
    dark = (img.max(axis=2) < 80)[330:350, 10:250]
    assert 30 < dark.any(axis=0).sum() < 240
