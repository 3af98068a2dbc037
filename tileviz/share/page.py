"""A replayed run as one self-contained web page that viser's player plays offline
(``python -m tileviz export-html``), or as a folder for static hosting (``--site``).

The page is a recording of a viser scene (``server.get_scene_serializer()``): the live demo's own
scene (:class:`tileviz.app.scene.SceneView`: floor grid, robot, truth, prediction and contracted
boxes, heading wedge, trails, the dataset's true path) is built on a private viser server that no
browser connects to, updated frame after frame from the run's records, with a pause of the frames'
time between them (``insert_sleep``). viser records only ``server.scene``, not GUI panels, so
what the live page shows in its left panel is drawn as images lying on the floor west of the room,
in a column that reads like that panel: the magnified set (:func:`tileviz.app.inset.render_inset`)
at the top, the camera view below it, then one pipeline stage. Labels above the room say the run's
name, its statuses and containment (the replay's summary) and the shown frame's status.

World frame as the live scene's (``docs/dataset-format.md``): metres, x east, y north, z up.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tileviz.share.files import atomic_output, check_folder, check_output
from tileviz.share.run import Run, Views, fit_width, with_room

if TYPE_CHECKING:
    from viser.infra import StateSerializer

    from tileviz.pipeline import FrameRecord

__all__ = ["DEFAULT_STAGE", "PageOptions", "build_page", "page_views", "export_html", "export_site",
           "page_html", "site_index"]

DEFAULT_STAGE = "lines"
"""The pipeline stage drawn by default: the grout lines vision found."""
FULL_TRAIL_EVERY = 20
"""The long trails are re-sent every this many shown frames (their newest part, the trail
heads, with every frame): the live page's rhythm, and most of the page's size otherwise."""
RECORDING = "run.viser"
"""The recording's name in a ``--site`` folder."""


@dataclass(frozen=True)
class PageOptions:
    """What a page shows. ``every``: every Nth frame of the run (the player waits N frame
    periods between them, so it plays in real time); ``image_px``: width of the camera and
    stage images and side of the magnified set, pixels; ``stage``: the pipeline stage drawn
    (a key of ``VisionResult.stages``; None: none); ``jpeg_quality``: of the images, 1..100."""

    every: int = 1
    image_px: int = 200
    stage: str | None = DEFAULT_STAGE
    jpeg_quality: int = 60

    def __post_init__(self) -> None:
        if not isinstance(self.every, int) or self.every < 1:
            raise ValueError(f"--every must be an integer >= 1, got {self.every!r}")
        if not isinstance(self.image_px, int) or not 32 <= self.image_px <= 2048:
            raise ValueError(f"--image-size must be 32 to 2048 pixels, got {self.image_px!r}")
        if not 1 <= int(self.jpeg_quality) <= 100:
            raise ValueError(f"--jpeg-quality must be 1 to 100, got {self.jpeg_quality!r}")


def page_views(opts: PageOptions) -> Views:
    """What :func:`tileviz.share.run.load_run` should keep for a page of ``opts``: its images
    as the replay made them, so vision runs once."""
    return Views(every=opts.every, width=opts.image_px, stage=opts.stage,
                 quality=int(opts.jpeg_quality))


def _on_floor(image: np.ndarray) -> np.ndarray:
    """An image (row 0 at the top) as viser lays it on the floor (row 0 at -y): upright for a
    viewer looking north."""
    return np.ascontiguousarray(image[::-1])


def _headline(run: Run) -> str:
    return f"{run.name}: frames {run.start} to {run.end - 1}; {run.summary()}"


def _frame_line(rec: FrameRecord, dt: float) -> str:
    inside = rec.truth_inside()
    where = ("" if inside is None else
             "; truth inside the set" if inside else "; truth OUTSIDE the set")
    obs = "a view" if rec.vision.observation is not None else "no view"
    return (f"frame {rec.index}, t = {rec.t:.2f} s: {rec.status}, {len(rec.updated)} "
            f"box{'es' if len(rec.updated) != 1 else ''}, {obs}{where}")


class _Panels:
    """The left panel's images, lying on the floor west of the room (see the module
    docstring)."""

    def __init__(self, scene: Any, run: Run, half: float, opts: PageOptions,
                 sample: np.ndarray) -> None:
        self.opts = opts
        px = opts.image_px
        cam = fit_width(sample, px)
        aspect = cam.shape[0] / cam.shape[1]
        width = 0.62 * half  # metres: the column fits beside the room, as high as it
        gap = 0.08 * half
        x = -half - gap - width / 2
        top = half
        self.slots: list[tuple[str, Any]] = []
        rows = [("inset", "the set, magnified (green prediction, blue set, pink truth)", 1.0),
                ("camera", "camera view", aspect)]
        if opts.stage is not None:
            rows.append(("stage", f"pipeline stage: {opts.stage}", aspect))
        for key, text, a in rows:
            h = width * a
            y = top - 0.05 * half - h / 2
            blank = np.full((max(1, int(round(px * a))), px, 3), 246, np.uint8)
            handle = scene.add_image(f"/panels/{key}", blank, width, h, format="jpeg",
                                     jpeg_quality=int(opts.jpeg_quality),
                                     position=(x, y, 0.003), cast_shadow=False,
                                     receive_shadow=False)
            scene.add_label(f"/panels/{key}_label", text, position=(x - width / 2, top, 0.01),
                            anchor="bottom-left", font_screen_scale=0.8)
            self.slots.append((key, handle))
            top = y - h / 2 - 0.04 * half
        self.left = x - width / 2
        self.bottom = top
        self.tile_size = run.cfg.floor.tile_size

    def show(self, run: Run, rec: FrameRecord) -> None:
        from tileviz.app.inset import render_inset

        px = self.opts.image_px
        image: np.ndarray | None = None
        for key, handle in self.slots:
            if key == "inset":
                handle.image = _on_floor(render_inset(rec, self.tile_size, px))
                continue
            name = "camera" if key == "camera" else self.opts.stage
            assert name is not None
            shown = run.kept_view(rec, name)
            if shown is None and (rec.index not in run.views or name == "camera"):
                # not kept by the replay: made again from the dataset
                image = run.image(rec) if image is None else image
                shown = image if key == "camera" else run.stage(rec, name, image=image)
            if shown is None:  # this frame's extractor drew no such stage
                shown = np.full_like(handle.image, 246)
            handle.image = _on_floor(fit_width(shown, px))


def build_page(run: Run, opts: PageOptions = PageOptions(),
               on_frame: Callable[[FrameRecord], None] | None = None) -> StateSerializer:
    """The run's scene recorded frame after frame (see the module docstring) on a private viser
    server, stopped before returning; serialise the result with ``as_html()`` or
    ``serialize()``. ``on_frame`` gets every frame drawn (a progress bar). ValueError when
    ``opts.stage`` is not a stage of the run's extractor."""
    import viser

    from tileviz.app.commands import LAYERS
    from tileviz.app.scene import SceneView
    from tileviz.app.sources import DatasetReplay

    picks = run.picks(opts.every)
    first = run.image(picks[0])
    if opts.stage is not None and run.stage(picks[0], opts.stage, image=first) is None:
        from tileviz.vision import extract

        v = extract(first, camera=run.cfg.camera, tile_size=run.cfg.floor.tile_size,
                    vision=run.cfg.vision, keep_stages=True)
        raise ValueError(f"--stage {opts.stage}: the {run.cfg.vision.extractor} extractor has no "
                         f"such stage (choose from {', '.join(v.stages) or 'none'})")
    source = DatasetReplay(run.folder)
    half = source.floor_half_size(run.cfg.sim.room_half_size)
    cfg = with_room(run.cfg, half)
    with contextlib.redirect_stdout(io.StringIO()):  # viser's address banner: nobody connects
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        scene = server.scene
        scene.set_up_direction("+z")
        scene.configure_default_lights(enabled=True, cast_shadow=False)
        view = SceneView(scene)
        layers = dict.fromkeys(LAYERS, True)
        layers.update(floor=False, setpoint=False, particles=False)
        view.layers = layers
        view.set_world(cfg, path=source.path(), waypoints=(), setpoint_kind="dataset",
                       closed=False)
        panels = _Panels(scene, run, half, opts, first)
        scene.add_label("/title", _headline(run), position=(panels.left, half + 0.22 * half,
                                                            0.01), anchor="bottom-left")
        status = scene.add_label("/status", _frame_line(picks[0], run.dt),
                                 position=(panels.left, half + 0.1 * half, 0.01),
                                 anchor="bottom-left")
        # the whole layout (panels and room) in view, seen from the south and above
        cx, cy = (panels.left + half) / 2.0, 0.1 * half
        span = half - panels.left
        server.initial_camera.position = (cx, cy - 0.3 * span, 0.62 * span)
        server.initial_camera.look_at = (cx, cy, 0.0)
        truth = np.full((len(picks), 2), math.nan)
        est = np.full((len(picks), 2), math.nan)
        serializer = server.get_scene_serializer()
        for k, rec in enumerate(picks):
            if rec.truth is not None:
                truth[k] = (rec.truth.x, rec.truth.y)
            hull = rec.updated.hull()
            if hull is not None and rec.status != "lost":
                est[k] = hull.centre[:2]
            view.show(rec, truth[: k + 1], est[: k + 1], full=k % FULL_TRAIL_EVERY == 0)
            panels.show(run, rec)
            status.text = _frame_line(rec, run.dt)
            if on_frame is not None:
                on_frame(rec)
            serializer.insert_sleep(run.dt * opts.every)
        return serializer
    finally:
        with contextlib.redirect_stdout(io.StringIO()):  # viser says it stopped
            server.stop()


def page_html(serializer: StateSerializer) -> str:
    """The recorded page as one self-contained HTML document (viser's client and the
    recording inline)."""
    from tileviz.app.server import HIDE_SOFTWARE_WEBGL_NOTICE

    html = serializer.as_html()
    head = html.index("</head>")
    return html[:head] + HIDE_SOFTWARE_WEBGL_NOTICE + html[head:]


def export_html(run: Run, out: str | os.PathLike[str], opts: PageOptions = PageOptions(),
                on_frame: Callable[[FrameRecord], None] | None = None) -> Path:
    """Write the run's page to ``out`` (a ``.html`` file, written whole or not at all); its
    path."""
    path = check_output(out, "OUT", (".html", ".htm"))
    html = page_html(build_page(run, opts, on_frame))
    with atomic_output(path) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return path


def site_index() -> str:
    """viser's client page, opening :data:`RECORDING` beside it when its address names no
    other recording (``?playbackPath=...``)."""
    from viser.infra import StateSerializer

    client = Path(StateSerializer.as_html.__code__.co_filename).parent.parent / "client" / \
        "build" / "index.html"
    text = client.read_text(encoding="utf-8")
    script = ("<script>if(!new URLSearchParams(location.search).has('playbackPath')){"
              f"history.replaceState(null,'','?playbackPath={RECORDING}'+location.hash)}}"
              "</script>")
    head = text.index("<head>") + len("<head>")
    return text[:head] + script + text[head:]


def export_site(run: Run, folder: str | os.PathLike[str], opts: PageOptions = PageOptions(),
                on_frame: Callable[[FrameRecord], None] | None = None) -> Path:
    """Write a folder for static hosting: ``index.html`` (viser's client, :func:`site_index`)
    and :data:`RECORDING` (the recording). The folder must not exist or be empty; it is made
    whole or not at all. Served over HTTP (a code host's pages, ``python -m http.server``):
    a browser does not let a page opened from ``file://`` read the recording beside it (the
    one-file page of :func:`export_html` has no such limit)."""
    import shutil
    import tempfile

    p = check_folder(folder, "--site")
    data = build_page(run, opts, on_frame).serialize()
    tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent))
    try:
        (tmp / "index.html").write_text(site_index(), encoding="utf-8")
        (tmp / RECORDING).write_bytes(data)
        os.chmod(tmp, 0o755)
        if p.exists():
            p.rmdir()
        os.replace(tmp, p)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return p
