"""Image panels: the camera view and every pipeline stage (report Fig 4.2), including the
(cos 4a, sin 4a) scatter with the segment bags (Fig 4.3), and under them the robust
extractor's checks (:func:`checks_text`: the readings tried and every check with its value,
limit and pass / fail, the refusing check first), for the frame being shown.

The history keeps each frame's images as JPEG bytes (:class:`tileviz.app.history.Entry`); a panel
decodes them and hands viser the pixels through its public ``GuiImageHandle.image`` setter, which
JPEG-encodes them again for the browser. Showing a frame that is already shown sends nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from tileviz.app.history import JPEG_QUALITY, Entry
from tileviz.vision.decision import explain_markdown
from tileviz.vision.result import VisionResult

if TYPE_CHECKING:
    from viser import GuiApi, GuiImageHandle, GuiMarkdownHandle

__all__ = ["ImagePanels", "ImageSlot", "checks_text", "decode_jpeg"]

STAGE_TITLES: dict[str, str] = {
    "camera": "camera view",
    "raw": "raw camera image (lens distortion and tilt)",
    "rectified": "rectified to the orthographic view",
    "input": "input",
    "gray": "gray",
    "laplacian": "Laplacian",
    "canny": "Canny edges",
    "edges": "edges",
    "morphology": "close + dilate",
    "warped": "de-rotated",
    "hough": "Hough segments",
    "bags": "bags (green y1, blue y2, red outliers)",
    "lines": "lines by bag (green y1, blue y2, red outliers)",
    "lattice": "lattice of the observation",
    "foreign": "foreign lines",
    "disambiguation": "(cos 4a, sin 4a) and bags",
}
"""Panel titles of the stage names the extractors use (other names are shown as they are)."""


EMPTY_LEVEL = 12
"""A stage image whose brightest pixel is at most this level (0..255; JPEG's ringing on black
stays well below it) shows nothing: its label says "none found"."""


def checks_text(vision: VisionResult) -> str:
    """Markdown of how the extractor decided on a frame: a heading, then the decision path
    (:func:`~tileviz.vision.decision.explain_markdown`: a summary naming the refusing check
    with its value and limit, then one table per block, the view and each reading tried:
    check, value, limit, result); a line saying the faithful extractor records none."""
    if vision.decision is None:
        return (f"*Checks: the {vision.extractor or 'chosen'} extractor records no decision "
                "path (the robust extractor does).*")
    return "**Checks of this frame**\n\n" + explain_markdown(vision.decision)


def decode_jpeg(data: bytes) -> np.ndarray:
    """HxWx3 uint8 RGB pixels of JPEG ``data``; ValueError when they do not decode."""
    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"not a decodable JPEG image ({len(data)} bytes)")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


class ImageSlot:
    """One GUI image element showing JPEG bytes (``gui``: a viser ``GuiApi``)."""

    def __init__(self, gui: GuiApi, blank: np.ndarray, *, label: str = "",
                 visible: bool = True) -> None:
        self.handle: GuiImageHandle = gui.add_image(blank, label=label, format="jpeg",
                                                    jpeg_quality=JPEG_QUALITY, visible=visible)
        self._data = b""
        self.empty = False
        """The image shown is black all over (a stage that found nothing to draw)."""

    def show(self, data: bytes) -> None:
        """Show the image ``data`` (JPEG bytes); nothing is sent when it is already shown."""
        if data != self._data:
            pixels = decode_jpeg(data)
            self.handle.image = pixels
            self._data = data
            self.empty = int(pixels.max(initial=0)) <= EMPTY_LEVEL

    def forget(self) -> None:
        """The next :meth:`show` sends its image even if the bytes are the same."""
        self._data = b""


class ImagePanels:
    """A fixed pool of GUI image elements (made in the caller's current GUI container).

    ``gui``: a viser ``GuiApi``; ``slots``: image elements for the stages (the camera has its
    own). Unused slots are hidden; labels follow the extractor's stage names. Under the stage
    images, ``checks`` shows the frame's decision path (:func:`checks_text`) while the stages
    are shown (sent only then, and only when it changes)."""

    def __init__(self, gui: GuiApi, *, slots: int = 14, width: int = 320,
                 height: int = 240) -> None:
        blank = np.zeros((max(2, height), max(2, width), 3), np.uint8)
        self.camera = ImageSlot(gui, blank, label=STAGE_TITLES["camera"])
        self.note: GuiMarkdownHandle = gui.add_markdown("")
        self.stages = [ImageSlot(gui, blank, visible=False) for _ in range(slots)]
        self.checks: GuiMarkdownHandle = gui.add_markdown("", visible=False)
        self._shown: tuple[str, ...] = ()

    def show(self, entry: Entry, display: bool, stages: bool = True) -> None:
        """Show ``entry``'s images; stage slots only when ``display`` and ``stages`` (and the
        entry has them)."""
        images = dict(entry.images)
        if "camera" in images:
            self.camera.show(images["camera"])
        # the extractors' "input" stage is the camera view again
        names = tuple(n for n, _ in entry.images if n not in ("camera", "input")) \
            if display and stages else ()
        for slot, name in zip(self.stages, names, strict=False):
            slot.show(images[name])
            title = STAGE_TITLES.get(name, name) + (": none found" if slot.empty else "")
            if slot.handle.label != title:
                slot.handle.label = title
            slot.handle.visible = True
        for slot in self.stages[len(names):]:
            slot.handle.visible = False
        if not stages:
            text = "*The image pipeline's stages: choose \"Camera and stages\" above.*"
        elif not display:
            text = "*Stage images are off (`--no-display` or Layers > Stream stage images).*"
        elif not names:
            text = "*This frame was made with the stage images off: none stored.*"
        else:
            text = ""
        if self.note.content != text:
            self.note.content = text
        self._shown = names
        # the checks: whatever the stage images, with the stages panel only
        if stages:
            table = checks_text(entry.record.vision)
            if self.checks.content != table:
                self.checks.content = table
        if self.checks.visible != stages:
            self.checks.visible = stages
