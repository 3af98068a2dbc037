"""Image panels: the camera view and every pipeline stage (report Fig 4.2), including the
(cos 4a, sin 4a) scatter with the segment bags (Fig 4.3), for the frame being shown.

The images were JPEG-encoded once when the frame was made (:class:`tileviz.app.history.Entry`);
the panels hand those bytes to viser as they are, so a frame from the history shows exactly what
was shown live, and showing a frame costs no encoding.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tileviz.app.history import Entry

__all__ = ["ImagePanels", "set_jpeg"]

STAGE_TITLES: dict[str, str] = {
    "camera": "camera view",
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


def set_jpeg(handle: Any, data: bytes) -> None:
    """Show already JPEG-encoded ``data`` in a viser GUI image ``handle``.

    viser's ``GuiImageHandle.image`` setter would decode nothing and re-encode an array; its
    ``_data``/``_format`` props carry the encoded bytes to the browser, so they are set directly
    (viser skips the update when the bytes are unchanged)."""
    handle._format = "jpeg"
    handle._data = data


class ImagePanels:
    """A fixed pool of GUI image elements (made in the caller's current GUI container).

    ``gui``: a viser ``GuiApi``; ``slots``: image elements for the stages (the camera has its
    own). Unused slots are hidden; labels follow the extractor's stage names."""

    def __init__(self, gui: Any, *, slots: int = 12, width: int = 320, height: int = 240) -> None:
        blank = np.zeros((max(2, height), max(2, width), 3), np.uint8)
        self.camera = gui.add_image(blank, label=STAGE_TITLES["camera"], format="jpeg")
        self.note = gui.add_markdown("")
        self.stages = [gui.add_image(blank, label="", format="jpeg", visible=False)
                       for _ in range(slots)]
        self._shown: tuple[str, ...] = ()

    def show(self, entry: Entry, display: bool) -> None:
        """Show ``entry``'s images; stage slots only when ``display`` (and the entry has them)."""
        images = dict(entry.images)
        if "camera" in images:
            set_jpeg(self.camera, images["camera"])
        # the extractors' "input" stage is the camera view again
        names = tuple(n for n, _ in entry.images if n not in ("camera", "input")) if display \
            else ()
        for slot, name in zip(self.stages, names, strict=False):
            if slot.label != STAGE_TITLES.get(name, name):
                slot.label = STAGE_TITLES.get(name, name)
            set_jpeg(slot, images[name])
            slot.visible = True
        for slot in self.stages[len(names):]:
            slot.visible = False
        if not display:
            text = "*Stage images are off (`--no-display` or the Display checkbox).*"
        elif not names:
            text = "*This frame was made with the display off: no stage images stored.*"
        else:
            text = ""
        if self.note.content != text:
            self.note.content = text
        self._shown = names
