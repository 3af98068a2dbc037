"""An observation does not depend on the machine's core count (docs/guarantees.md,
"Reproducibility").

``data/canny_threads_frame.png`` is frame 1597 of a recorded default-preset run: on 2 OpenCV
threads, Canny's stripes give it other edge pixels than on 1 thread, and the robust extractor's
observation moved in its 7th digit. Importing tileviz.vision puts OpenCV on one thread, so a
process started with OpenCV on 2 threads extracts the same observation as this one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2

from tileviz.config import preset
from tileviz.vision import extract

FRAME = Path(__file__).parent / "data" / "canny_threads_frame.png"

_CHILD = """
import json, sys
import cv2
cv2.setNumThreads(2)  # what a program (or OPENCV_FOR_THREADS_NUM) may have set before
from tileviz.config import preset
from tileviz.vision import extract
cfg = preset("default")
rgb = cv2.cvtColor(cv2.imread(sys.argv[1], cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
res = extract(rgb, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision)
o = res.observation
print(json.dumps({"threads": cv2.getNumThreads(),
                  "y": None if o is None else [o.y1, o.y2, o.y3]}))
"""


def _here() -> list[float] | None:
    cfg = preset("default")
    rgb = cv2.cvtColor(cv2.imread(str(FRAME), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    o = extract(rgb, camera=cfg.camera, tile_size=cfg.floor.tile_size,
                vision=cfg.vision).observation
    return None if o is None else [o.y1, o.y2, o.y3]


def test_importing_vision_puts_opencv_on_one_thread() -> None:
    assert cv2.getNumThreads() == 1


def test_observation_is_the_same_in_a_process_that_had_two_threads() -> None:
    env = dict(os.environ, OPENCV_FOR_THREADS_NUM="2")
    out = subprocess.run([sys.executable, "-c", _CHILD, str(FRAME)], capture_output=True,
                         text=True, env=env, timeout=600, check=True)
    child = json.loads(out.stdout.strip().splitlines()[-1])
    assert child["threads"] == 1
    here = _here()
    assert here is not None, "the stored frame gives an observation"
    assert child["y"] == here  # bit for bit, not approximately
