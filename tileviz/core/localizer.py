"""The guaranteed interval localizer: a set of robot poses kept as a few disjoint boxes.

Each :meth:`Localizer.step`: predict the set with the bounded odometry (docs/method.md,
"Prediction"), intersect its heading with the compass, then contract it with the tile observation
(docs/method.md, "Contraction"), every bound rounded outward. Frames and units as in
``docs/dataset-format.md``: metres, radians, heading continuous (not wrapped).

Contract: under the hypotheses of ``docs/guarantees.md`` (H1-H4; H5 with recovery on), at every
frame whose status is not ``lost`` the true pose is inside ``LocalizerStep.predicted`` and
``LocalizerStep.updated`` (heading modulo 2 pi); the proof is in docs/method.md, "Why the set
holds the truth". ``odometry=None`` means the robot did not move since the previous step (frame
0, after a reset). Statuses (``docs/dataset-format.md``, ``docs/method.md``): ``contracted``,
``predicted`` (no view, or mode ``odometry``), ``rejected`` (the view fits no pose of the set:
not used, the prediction kept), ``lost`` (``max_rejections`` rejections in a row; frames without
a view neither count nor reset the streak; the set is then the hull of the prediction, views are
ignored, until :meth:`Localizer.reset`). A compass reading that misses the predicted set is
ignored that frame (``LocalizerStep.compass_rejected``).

Recovery (``LocalizerConfig.max_slip = (d, a)``, metres and radians; mode ``autonomous``; off
when both are 0): a rejected view, or a compass that misses the set, keeps the prediction and adds
the slip candidates, the poses within (d, d, a) of it that the compass and the view allow, one box
per lattice cell (docs/method.md, "Recovery"); for ``slip_window`` frames after that, every view
contracts the prediction widened by ``max_slip``.

Fault model (``LocalizerConfig.fault_speed`` m/s, ``fault_yaw_rate`` rad/s; on by default; mode
``autonomous``; off when both are 0, or when the ``max_slip`` recovery is on): a second set, the
fault set, is predicted with the odometry bounds widened by the model, cut by the compass when the
compass meets it, and contracted by every view. When a view or the compass rejects the set, the set
becomes the fault set's contraction (``reinflated``, status ``contracted``); a view that fits
neither counts as a rejection (so does a frame without a view whose compass misses both sets), and
:data:`FAULT_MAX_REJECTIONS` of those in a row make the status ``lost``. For ``slip_window`` frames
after the fault set was taken, the set is the fault set's contraction whenever the view cuts it to
at most ``max_boxes`` boxes (``LocalizerStep.fault_frame`` counts them): a slip still going on is
followed rather than noticed again, frames late. Under H1, H2' (the true speed and yaw rate within
the widened bounds), H3 and H4 the fault set holds the truth at every frame
(``docs/guarantees.md``).

Modes (``LocalizerConfig.mode``): ``autonomous``; ``truth`` (every frame the set restarts from
the true pose inflated by ``truth_inflation``, then the compass and the view contract it; never
``lost``); ``odometry`` (prediction and compass only, status ``predicted``).

The hot path computes on :class:`tileviz.types.Box` (a named tuple) throughout, as the public
API does. Its shortcuts (one-box cases, cos and sin ranges in one call, lattice walks that reuse
their piece bounds, only the rotation branches the heading meets) compute the very same floats
as the general code: ``tests/test_localizer_golden.py`` compares every output bit of recorded
sequences.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from tileviz.config import LocalizerConfig
from tileviz.core.boxes import (
    MIN_TILE,
    ONE_TURN,
    checked_box,
    finite,
    hull_of,
    in_range,
    inflate_box,
    nonnegative,
    one_turn,
    tidy,
)
from tileviz.core.constants import LIMIT
from tileviz.core.contraction import Window, contract_view, lever_enclosure, view_window
from tileviz.core.prediction import compass_pieces, predict_box
from tileviz.types import Box, BoxSet, Observation, Odometry, Pose, SensorBounds, Status

__all__ = ["FAULT_MAX_REJECTIONS", "RELOCALIZE_MAX_CANDIDATES", "Localizer", "LocalizerStep",
           "region_candidates"]

FAULT_MAX_REJECTIONS = 5
"""With the fault model on, a view that fits neither the set nor the fault set means the motion
went beyond the fault model (a kidnap) or the view is an outlier; this many in a row and the
status is ``lost`` (``max_rejections`` if smaller): never more frames vouching for a set that
may have lost the truth."""

RELOCALIZE_MAX_CANDIDATES = 400
"""The most candidate boxes a re-localization region may need (:meth:`Localizer.relocalize`);
a larger region is refused rather than hulled into one wide box."""

_INF = math.inf
_nextafter = math.nextafter


class LocalizerStep(NamedTuple):
    """What one :meth:`Localizer.step` did (an immutable named tuple).

    ``predicted``: the set after prediction and compass (before the view). ``updated``: the set
    after this frame's update. ``status``: see the module docstring. ``passes``: the largest
    number of contraction passes run on one cell (0 when nothing was contracted). ``hulled``: the
    box cap (or a lattice split too fine to keep) replaced some set by its hull this frame.
    ``compass_rejected``: the compass reading missed the predicted set and was ignored.
    ``rejections``: the current streak of consecutive rejected views. ``reinflated``: recovery
    added the slip candidates to the set this frame (module docstring, "Recovery"), or the set was
    taken from the fault set (module docstring, "Fault model"). ``fault_frame``: fault model
    only: k >= 1 while the localizer follows a noticed fault (the k-th frame since the view or
    compass rejected the set and the fault set was taken; ``slip_window`` frames after the last
    such rejection), 0 otherwise. ``region``: the re-localization region (x0, y0, x1, y1,
    metres) this step's sets were cut to while its candidates remain (:meth:`Localizer.relocalize`;
    the hypothesis: the robot is in it), else None.
    """

    predicted: BoxSet
    updated: BoxSet
    status: Status
    passes: int
    hulled: bool = False
    compass_rejected: bool = False
    rejections: int = 0
    reinflated: bool = False
    fault_frame: int = 0
    region: tuple[float, float, float, float] | None = None

    @property
    def relocalizing(self) -> bool:
        """The set still holds the candidates of a re-localization, cut to :attr:`region`."""
        return self.region is not None


def region_candidates(region: tuple[float, float, float, float], tile_size: float,
                      heading: tuple[float, float] | None = None, lever: float = 0.0) -> int:
    """The most candidate boxes a re-localization in ``region`` (x0, y0, x1, y1, metres) can
    leave on a floor of ``tile_size`` m tiles, with the camera ``lever`` metres from the robot
    point (the norm of ``camera_offset``): the tile cells that the camera centre's range (the
    region widened by the lever) meets times the heading branches (a view's heading repeats
    every quarter turn) that ``heading`` (lo, hi rad; None: a whole turn) meets. After the first
    view every candidate is narrower than a tile and its motion and the next views never split
    it (docs/method.md, "Re-localization"), so the set never holds more boxes than this.
    ValueError, in words a user reads, when that exceeds :data:`RELOCALIZE_MAX_CANDIDATES`."""
    x0, y0, x1, y1 = region
    t_lo, t_hi = (-math.pi, math.pi) if heading is None else heading
    reach = 2.0 * abs(lever)
    nx = math.floor((x1 - x0 + reach) / tile_size) + 2
    ny = math.floor((y1 - y0 + reach) / tile_size) + 2
    branches = min(4, math.floor((t_hi - t_lo) / (math.pi / 2)) + 2)
    need = nx * ny * branches
    if need > RELOCALIZE_MAX_CANDIDATES:
        side = tile_size * max(1, math.isqrt(RELOCALIZE_MAX_CANDIDATES // branches) - 2) - reach
        hint = (f"a region of at most about {side:.3g} m x {side:.3g} m" if side > 0 else
                "a smaller region")
        raise ValueError(f"the region ({x0:g}, {y0:g})-({x1:g}, {y1:g}) m spans {nx} x {ny} "
                         f"tiles of {tile_size:g} m and {branches} heading branches: up to "
                         f"{need} candidate boxes, more than the {RELOCALIZE_MAX_CANDIDATES} "
                         f"re-localization can follow; give {hint}")
    return need


class Localizer:
    """Guaranteed localization on a tiled floor (see the module docstring for the guarantee).

    ``tile_size``: L, metres. ``camera_offset``: (forward, left) of the camera centre in the robot
    frame, metres. ``bounds``: odometry and compass error bounds. ``config``: mode, box cap,
    passes, truth inflation, rejection limit. ``initial``: a box known to contain the true pose.
    """

    def __init__(
        self,
        *,
        tile_size: float,
        camera_offset: tuple[float, float],
        bounds: SensorBounds,
        config: LocalizerConfig,
        initial: Box,
    ) -> None:
        self._L = finite("tile_size", tile_size)
        if self._L < MIN_TILE:
            raise ValueError(f"tile_size must be >= {MIN_TILE:g} m, got {tile_size!r}")
        if len(camera_offset) != 2:
            raise ValueError(f"camera_offset must be (forward, left), got {camera_offset!r}")
        off = (
            finite("camera_offset[0]", camera_offset[0]),
            finite("camera_offset[1]", camera_offset[1]),
        )
        self._lever = lever_enclosure(off)
        self._ev = nonnegative("speed_error", bounds.speed_error)
        self._ew = nonnegative("yaw_rate_error", bounds.yaw_rate_error)
        self._ec = nonnegative("compass_error", bounds.compass_error)
        if not isinstance(config, LocalizerConfig):
            raise ValueError(f"config must be a LocalizerConfig, got {type(config).__name__}")
        self._cfg = config
        self._inflation = tuple(
            nonnegative(f"truth_inflation[{i}]", v) for i, v in enumerate(config.truth_inflation)
        )
        if len(self._inflation) != 3:
            raise ValueError(f"truth_inflation needs 3 values, got {config.truth_inflation!r}")
        if len(config.max_slip) != 2:
            raise ValueError(f"max_slip must be (metres, radians), got {config.max_slip!r}")
        self._slip = (nonnegative("max_slip[0]", config.max_slip[0]),
                      nonnegative("max_slip[1]", config.max_slip[1]))
        self._recover = config.mode == "autonomous" and (self._slip[0] > 0 or self._slip[1] > 0)
        fv = nonnegative("fault_speed", config.fault_speed)
        fw = nonnegative("fault_yaw_rate", config.fault_yaw_rate)
        self._faulty = config.mode == "autonomous" and (fv > 0 or fw > 0) and not self._recover
        """The fault model is on: the fault set is kept (module docstring, "Fault model"). A
        ``max_slip`` recovery replaces it (an explicit recovery setting wins over the default
        model)."""
        n = _nextafter
        self._fault_bounds = (n(self._ev + fv, _INF), n(self._ew + fw, _INF))
        self._fault: list[Box] = []
        self._boxes: list[Box] = []
        self._rejections = 0
        self._lost = False
        self._window = 0
        self._fault_frame = 0
        self._region: tuple[float, float, float, float] | None = None
        self._cap = config.max_boxes
        self.reset(initial)

    def reset(self, box: Box) -> None:
        """Start again from ``box`` (it must contain the true pose): clears the rejection streak
        and the ``lost`` state."""
        self._boxes = [checked_box("initial box", box)]
        self._fault = list(self._boxes)
        self._rejections = 0
        self._lost = False
        self._window = 0
        self._fault_frame = 0
        self._region = None
        self._cap = self._cfg.max_boxes

    def relocalize(self, region: tuple[float, float, float, float],
                   heading: tuple[float, float] | None = None, *,
                   compass: float | None = None) -> int:
        """Start again from "somewhere in ``region``" = (x0, y0, x1, y1), metres, x0 <= x1,
        y0 <= y1 (the robot's point between the wheels, at the pose of the last step), heading
        within ``heading`` = (lo, hi), rad, or within ``compass_error`` of ``compass`` (that
        step's reading, rad), or anywhere (both None: the compass of the next frames cuts it).
        Clears the ``lost`` state like :meth:`reset`.

        The next view cuts the region into one candidate box per lattice cell (the floor repeats:
        every tile in the region offers a pose that fits the view), so the set may hold that many
        boxes: the box cap becomes the count :func:`region_candidates` bounds while candidates
        remain (never a hull of candidates). Until one candidate remains (a single box narrower
        than a tile in x and y), every set is cut to the region: candidates whose motion takes
        them out of it are dropped, which breaks the floor's symmetry. Hypothesis (H1 for this
        start, ``docs/guarantees.md``): the robot is in the region from now until one candidate
        remains. Returns the number of candidate boxes allowed; ValueError (nothing changed)
        when the region would need more than :data:`RELOCALIZE_MAX_CANDIDATES`, or on a bad
        bound."""
        x0, y0, x1, y1 = region = self._region_of(region)
        t_lo, t_hi = heading = self._heading_of(heading, compass)
        need = self.candidates(region, heading)
        self.reset(Box(x0, x1, y0, y1, t_lo, t_hi))
        self._region = region
        self._cap = max(self._cfg.max_boxes, need)
        return self._cap

    def candidates(self, region: tuple[float, float, float, float],
                   heading: tuple[float, float] | None = None, *,
                   compass: float | None = None) -> int:
        """The candidate boxes :meth:`relocalize` would allow for these arguments
        (:func:`region_candidates` with this floor and camera), changing nothing; ValueError as
        :meth:`relocalize`."""
        lever = 0.0 if self._lever is None else self._lever[1]
        return region_candidates(self._region_of(region), self._L,
                                 self._heading_of(heading, compass), lever)

    @staticmethod
    def _region_of(region: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        """``region`` checked: four finite numbers, x0 <= x1, y0 <= y1 (ValueError)."""
        if len(region) != 4:
            raise ValueError(f"region must be (x0, y0, x1, y1), got {region!r}")
        x0, y0, x1, y1 = (finite(f"region[{i}]", v) for i, v in enumerate(region))
        if x0 > x1 or y0 > y1:
            raise ValueError(f"region must have x0 <= x1 and y0 <= y1, got {region!r}")
        return (x0, y0, x1, y1)

    def _heading_of(self, heading: tuple[float, float] | None,
                    compass: float | None) -> tuple[float, float]:
        """The heading interval of a re-localization (rad): ``heading``, else ``compass`` +-
        ``compass_error`` (outward), else a whole turn."""
        if heading is None and compass is not None:
            c = finite("compass", compass)
            heading = (_nextafter(c - self._ec, -_INF), _nextafter(c + self._ec, _INF))
        t_lo, t_hi = (-math.pi, math.pi) if heading is None else heading
        return (finite("heading[0]", t_lo), finite("heading[1]", t_hi))

    @property
    def region(self) -> tuple[float, float, float, float] | None:
        """The re-localization region (x0, y0, x1, y1, metres) while its candidates remain, else
        None (:meth:`relocalize`)."""
        return self._region

    def _in_region(self, boxes: list[Box]) -> list[Box]:
        """The parts of ``boxes`` whose x and y lie in the re-localization region (exact: min and
        max of floats)."""
        region = self._region
        assert region is not None
        x0, y0, x1, y1 = region
        out = []
        for b in boxes:
            xl, xh, yl, yh = max(b[0], x0), min(b[1], x1), max(b[2], y0), min(b[3], y1)
            if xl <= xh and yl <= yh:
                out.append(Box(xl, xh, yl, yh, b[4], b[5]))
        return out

    @property
    def current(self) -> BoxSet:
        """The set after the last step (or the initial box)."""
        return BoxSet(tuple(self._boxes))

    @property
    def lost(self) -> bool:
        """True once the localizer declared itself lost (until :meth:`reset`)."""
        return self._lost

    def step(
        self,
        odometry: Odometry | None,
        compass: float | None,
        observation: Observation | None,
        truth: Pose | None = None,
    ) -> LocalizerStep:
        """One frame: predict with ``odometry`` (the motion since the previous step; None = no
        motion, e.g. frame 0), intersect with ``compass`` (rad, wrapped to (-pi, pi], or None),
        contract with ``observation`` (or None). ``truth`` is needed in mode ``truth`` only.
        Raises ValueError naming the quantity on NaN/inf, negative dt, negative bounds (a bad
        frame changes nothing).

        One regime a frame (module docstring): the fault model (:meth:`_step_fault_model`), the
        ``max_slip`` recovery (:meth:`_step_recovery`), or neither (:meth:`_step_plain`: also
        every mode but ``autonomous``, and every frame once ``lost``)."""
        self._check_inputs(odometry, compass, observation, truth)
        if self._lost:
            return self._step_plain(odometry, compass, observation, truth)
        if self._faulty:
            return self._step_fault_model(odometry, compass, observation)
        if self._recover:
            return self._step_recovery(odometry, compass, observation)
        return self._step_plain(odometry, compass, observation, truth)

    def _check_inputs(self, odometry: Odometry | None, compass: float | None,
                      observation: Observation | None, truth: Pose | None) -> None:
        """ValueError naming the first bad input of a frame (see :meth:`step`). The fast test:
        every value within +-LIMIT (NaN fails, a non-number raises TypeError); on failure the
        checks that name the culprit run."""
        lim = LIMIT
        neg_lim = -LIMIT
        if odometry is not None:
            v, w, dt = odometry.speed, odometry.yaw_rate, odometry.dt
            try:
                ok = neg_lim <= v <= lim and neg_lim <= w <= lim and 0 <= dt <= lim
            except TypeError:
                ok = False
            if not ok:
                finite("odometry.speed", v)
                finite("odometry.yaw_rate", w)
                nonnegative("odometry.dt", dt)
        if compass is not None:
            try:
                ok = neg_lim <= compass <= lim
            except TypeError:
                ok = False
            if not ok:
                finite("compass", compass)
        if observation is not None:
            o = observation
            e, e3 = o.position_error, o.heading_error
            try:
                ok = (neg_lim <= o.y1 <= lim and neg_lim <= o.y2 <= lim and neg_lim <= o.y3 <= lim
                      and 0 <= e <= lim and 0 <= e3 <= lim)
            except TypeError:
                ok = False
            if not ok:
                finite("observation.y1", o.y1)
                finite("observation.y2", o.y2)
                finite("observation.y3", o.y3)
                nonnegative("observation.position_error", e)
                nonnegative("observation.heading_error", e3)
        if truth is not None:
            tx, ty, tt = truth.x, truth.y, truth.theta
            try:
                ok = neg_lim <= tx <= lim and neg_lim <= ty <= lim and neg_lim <= tt <= lim
            except TypeError:
                ok = False
            if not ok:
                finite("truth.x", tx)
                finite("truth.y", ty)
                finite("truth.theta", tt)
        elif self._cfg.mode == "truth":
            raise ValueError("truth: mode 'truth' needs the true pose every frame, got None")

    # --- the three regimes -----------------------------------------------------------------------

    def _step_plain(self, odometry: Odometry | None, compass: float | None,
                    observation: Observation | None, truth: Pose | None) -> LocalizerStep:
        """Neither the fault model nor recovery: predict, cut by the compass (ignored when it
        misses the set), contract by the view; a view that fits no pose of the set is
        ``rejected`` and ``max_rejections`` of those in a row (mode ``autonomous``) are
        ``lost``. Once ``lost``: the hull of the prediction, views ignored."""
        cfg = self._cfg
        cap = self._cap
        boxes, hulled = self._predict(odometry, truth, cap)
        compass_rejected = False
        if compass is not None:
            cut, h = self._cut_by_compass(boxes, compass, cap)
            if cut is None:
                compass_rejected = True
            else:
                boxes = cut
                hulled = hulled or h
        relocalizing = self._region is not None and not self._lost
        if relocalizing:
            boxes = self._in_region(boxes) or boxes
        predicted = BoxSet(tuple(boxes))
        passes = 0
        status: Status
        if self._lost and cfg.mode != "truth":
            status = "lost"
            updated = [hull_of(boxes)]
        elif cfg.mode == "odometry" or observation is None:
            status = "predicted"
            updated = boxes
        else:
            out, passes, h = self._contract_all(boxes, view_window(observation))
            hulled = hulled or h
            if relocalizing and out:
                out = self._in_region(out)  # none left: the view fits no candidate in it
            if out:
                status, updated, h = self._contracted(out, cap)
                hulled = hulled or h
            else:
                status, updated = self._rejected(boxes, cfg.max_rejections)
        return self._finish(predicted, boxes, updated, status, passes, hulled, compass_rejected,
                            False, relocalizing)

    def _step_recovery(self, odometry: Odometry | None, compass: float | None,
                       observation: Observation | None) -> LocalizerStep:
        """The ``max_slip`` recovery (module docstring, "Recovery"), mode ``autonomous``, not
        ``lost``: a compass or a view that misses the prediction keeps it and adds the slip
        candidates; for ``slip_window`` frames after, the view contracts the prediction widened
        by ``max_slip``."""
        cfg = self._cfg
        cap = self._cap
        boxes, hulled = self._predict(odometry, None, cap)
        raw = boxes  # the prediction before the compass: what recovery inflates
        following = self._tick_window()  # a fault noticed lately: follow it
        compass_rejected = False
        reinflated = False
        if compass is not None:
            cut, h = self._cut_by_compass(boxes, compass, cap)
            if cut is None:
                # the prediction misses the compass: keep it (the compass may be the outlier)
                # and add the slip candidates the compass allows (the odometry may be)
                compass_rejected = True
                self._window = cfg.slip_window
                extra, _, h = self._slip_candidates(raw, compass, None)
                if extra:
                    boxes, h2 = tidy(boxes + extra, cap)
                    hulled = hulled or h or h2
                    reinflated = True
            else:
                boxes = cut
                hulled = hulled or h
        relocalizing = self._region is not None
        if relocalizing:
            boxes = self._in_region(boxes) or boxes
        predicted = BoxSet(tuple(boxes))
        passes = 0
        status: Status
        if observation is None:
            status = "predicted"
            updated = boxes
        else:
            view = view_window(observation)
            if following:
                # within slip_window frames of a noticed fault: the view contracts the prediction
                # inflated by max_slip (it holds the plain prediction)
                out, passes, h = self._slip_candidates(raw, compass, view)
                reinflated = bool(out)
            else:
                out, passes, h = self._contract_all(boxes, view)
            hulled = hulled or h
            if relocalizing and out:
                out = self._in_region(out)
            if out:
                status, updated, h = self._contracted(out, cap)
                hulled = hulled or h
            else:
                # the view misses the prediction: either the view is the outlier (keep the
                # prediction) or the odometry is (keep what the view allows within max_slip)
                self._window = cfg.slip_window
                updated = boxes
                if not following:  # (when following, that set was just found empty)
                    extra, p, h = self._slip_candidates(raw, compass, view)
                    passes = max(passes, p)
                    hulled = hulled or h
                    if extra:
                        updated, h = tidy(boxes + extra, cap)
                        hulled = hulled or h
                        reinflated = True
                status, updated = self._rejected(updated, cfg.max_rejections)
        return self._finish(predicted, boxes, updated, status, passes, hulled, compass_rejected,
                            reinflated, relocalizing)

    def _step_fault_model(self, odometry: Odometry | None, compass: float | None,
                          observation: Observation | None) -> LocalizerStep:
        """The fault model (module docstring, "Fault model"), mode ``autonomous``, not ``lost``:
        the fault set is predicted and cut beside the set; when the compass or the view rejects
        the set, the set is taken from the fault set's contraction; a view that fits neither
        (or a compass that misses both, without a view) is a rejection, and
        :data:`FAULT_MAX_REJECTIONS` of those in a row are ``lost``."""
        cfg = self._cfg
        cap = self._cap
        boxes, hulled = self._predict(odometry, None, cap)
        fault, compass_beyond, h = self._predict_fault_set(odometry, compass, cap)
        hulled = hulled or h
        fault_following = self._tick_window()  # a fault noticed lately: the fault set first
        compass_rejected = False
        reinflated = False
        if compass is not None:
            cut, h = self._cut_by_compass(boxes, compass, cap)
            if cut is None:
                # the compass misses the prediction: the fault set holds what a fault allows
                compass_rejected = True
                boxes = fault
                reinflated = True
                self._window = cfg.slip_window
                self._fault_frame = 0
            else:
                boxes = cut
                hulled = hulled or h
        relocalizing = self._region is not None
        if relocalizing:
            boxes = self._in_region(boxes) or boxes
            fault = self._in_region(fault) or fault
        predicted = BoxSet(tuple(boxes))
        limit = min(cfg.max_rejections, FAULT_MAX_REJECTIONS)
        passes = 0
        status: Status
        if observation is None:
            status = "predicted"
            updated = boxes
            if compass_rejected and compass_beyond:
                # the compass fits neither the set nor the fault set (a turn beyond the model,
                # or a compass outlier): a rejection, as a view that fits neither, so frames
                # without a usable view cannot vouch for long for a set that misses the truth
                self._rejections += 1
                if self._rejections >= limit:
                    status = "lost"
                    updated = self._declare_lost(updated)
        else:
            view = view_window(observation)
            out, passes, view_hulled = self._contract_all(boxes, view)
            hulled = hulled or view_hulled
            # the set is taken from the fault set only when the view cuts it to a few disjoint
            # boxes: a hull (more cells than max_boxes) would be a wide box called contracted,
            # so such a frame counts as a rejection instead
            if fault_following and not reinflated and out:
                # within slip_window frames of a noticed fault: the set is the fault set's
                # contraction whenever the view fits it in a few boxes (a slip still going on is
                # followed, not noticed again frames later)
                got_f, _, f_hulled = self._contract_all(fault, view)
                hulled = hulled or f_hulled
                if got_f:
                    fault = got_f
                    if not f_hulled and len(got_f) <= cap:
                        out = got_f
                        reinflated = True
            elif reinflated:  # (boxes is the fault set already: contracted above)
                if out:
                    fault = out
                if view_hulled or len(out) > cap:
                    out = []
            else:
                got_f, _, f_hulled = self._contract_all(fault, view)
                hulled = hulled or f_hulled
                if got_f:
                    fault = got_f
                    if not out and not f_hulled and len(got_f) <= cap:
                        # the view rejects the prediction, not the fault set
                        out = got_f
                        reinflated = True
                        self._window = cfg.slip_window
                        self._fault_frame = 0
            if relocalizing and out:
                out = self._in_region(out)
            if out:
                status, updated, h = self._contracted(out, cap)
                hulled = hulled or h
            else:
                status, updated = self._rejected(boxes, limit)
        # the fault set after this frame
        if reinflated:  # the set was taken from the fault set: they agree again
            fault = updated
        elif len(fault) > 1:
            fault, h = tidy(fault, cap)
            hulled = hulled or h
        self._fault = fault
        self._fault_frame = (self._fault_frame + 1
                             if (reinflated or self._window > 0) and not self._lost else 0)
        return self._finish(predicted, boxes, updated, status, passes, hulled, compass_rejected,
                            reinflated, relocalizing, self._fault_frame)

    # --- the pieces the regimes share ------------------------------------------------------------

    def _predict(self, odometry: Odometry | None, truth: Pose | None,
                 cap: int) -> tuple[list[Box], bool]:
        """The set predicted for this frame (docs/method.md, "Prediction"): in mode ``truth``
        the inflated truth; else the last set moved by ``odometry`` +- its bounds (None: not
        moved). Returns (boxes, whether the cap ``cap`` hulled them)."""
        n = _nextafter
        if self._cfg.mode == "truth":
            assert truth is not None
            tx, ty, tt = truth.x, truth.y, truth.theta
            ix, iy, it = self._inflation
            return in_range([Box(n(tx - ix, -_INF), n(tx + ix, _INF), n(ty - iy, -_INF),
                                 n(ty + iy, _INF), n(tt - it, -_INF), n(tt + it, _INF))]), False
        if odometry is None:
            return list(self._boxes), False
        v, w, dt = odometry.speed, odometry.yaw_rate, odometry.dt
        v_lo, v_hi = n(v - self._ev, -_INF), n(v + self._ev, _INF)
        w_lo, w_hi = n(w - self._ew, -_INF), n(w + self._ew, _INF)
        prior = self._boxes
        boxes = ([predict_box(prior[0], v_lo, v_hi, w_lo, w_hi, dt)] if len(prior) == 1 else
                 [predict_box(b, v_lo, v_hi, w_lo, w_hi, dt) for b in prior])
        lim = LIMIT
        neg_lim = -LIMIT
        for b in boxes:
            if not (neg_lim <= b[0] and b[1] <= lim and neg_lim <= b[2] and b[3] <= lim
                    and neg_lim <= b[4] and b[5] <= lim and b[5] - b[4] <= ONE_TURN):
                boxes = in_range(boxes)  # raises, or cuts a heading to one turn
                break
        if len(boxes) > 1:  # (one box is tidy: cap >= 1, LocalizerConfig checks it)
            return tidy(boxes, cap)
        return boxes, False

    def _predict_fault_set(self, odometry: Odometry | None, compass: float | None,
                           cap: int) -> tuple[list[Box], bool, bool]:
        """The fault set predicted with the odometry bounds widened by the fault model, cut by
        the compass when the compass meets it. Returns (boxes, whether the compass misses it,
        whether the cap hulled it)."""
        fault = self._fault
        hulled = False
        if odometry is not None:
            n = _nextafter
            v, w, dt = odometry.speed, odometry.yaw_rate, odometry.dt
            ev, ew = self._fault_bounds
            fault = in_range([predict_box(b, n(v - ev, -_INF), n(v + ev, _INF),
                                           n(w - ew, -_INF), n(w + ew, _INF), dt)
                               for b in fault])
            if len(fault) > 1:
                fault, hulled = tidy(fault, cap)
        compass_beyond = False
        if compass is not None:
            cut = self._compass_cut(fault, compass)
            if cut:  # (a compass that misses the fault set too is ignored)
                fault, h = tidy(cut, cap)
                hulled = hulled or h
            else:
                compass_beyond = True
        return fault, compass_beyond, hulled

    def _tick_window(self) -> bool:
        """Whether this frame is within ``slip_window`` frames of a noticed fault (one frame of
        the window is used up)."""
        if self._window > 0:
            self._window -= 1
            return True
        return False

    def _cut_by_compass(self, boxes: list[Box], compass: float,
                        cap: int) -> tuple[list[Box] | None, bool]:
        """``boxes`` cut by the compass reading +- its bound (mod 2 pi): (the pieces, whether the
        cap hulled them), or (None, False) when the compass misses every box."""
        c_lo = _nextafter(compass - self._ec, -_INF)
        c_hi = _nextafter(compass + self._ec, _INF)
        cut = (compass_pieces(boxes[0], c_lo, c_hi) if len(boxes) == 1 else
               [p for b in boxes for p in compass_pieces(b, c_lo, c_hi)])
        if len(cut) == 1:
            return cut, False
        if cut:
            return tidy(cut, cap)
        return None, False

    def _contracted(self, out: list[Box], cap: int) -> tuple[Status, list[Box], bool]:
        """A frame whose view fits the set (``out``: the contracted pieces): the streak of
        rejections ends. Returns ("contracted", the set, whether the cap hulled it)."""
        self._rejections = 0
        if len(out) == 1:
            return "contracted", out, False
        boxes, hulled = tidy(out, cap)
        return "contracted", boxes, hulled

    def _rejected(self, boxes: list[Box], limit: int) -> tuple[Status, list[Box]]:
        """A frame whose view fits no pose of the set (``boxes``: what the set becomes): one
        more rejection in a row; ``limit`` of those in mode ``autonomous`` are ``lost``."""
        self._rejections += 1
        if self._cfg.mode == "autonomous" and self._rejections >= limit:
            return "lost", self._declare_lost(boxes)
        return "rejected", boxes

    def _declare_lost(self, boxes: list[Box]) -> list[Box]:
        """Enter the ``lost`` state (until :meth:`reset`); the set becomes the hull of
        ``boxes``."""
        self._lost = True
        self._window = 0
        return [hull_of(boxes)]

    def _finish(self, predicted: BoxSet, boxes: list[Box], updated: list[Box], status: Status,
                passes: int, hulled: bool, compass_rejected: bool, reinflated: bool,
                relocalizing: bool, fault_frame: int = 0) -> LocalizerStep:
        """Keep ``updated`` as the set (``boxes``: the prediction it may be), end a
        re-localization once one candidate is left (or ``lost``), and return the frame's
        :class:`LocalizerStep`."""
        region = self._region if relocalizing else None
        self._boxes = updated
        if relocalizing:
            b = updated[0]
            if self._lost or (len(updated) == 1 and b[1] - b[0] < self._L
                              and b[3] - b[2] < self._L):
                self._region = None  # one candidate left (or lost): plain tracking again
                self._cap = self._cfg.max_boxes
        return LocalizerStep(
            predicted,
            predicted if updated is boxes else BoxSet(tuple(updated)),
            status,
            passes,
            hulled,
            compass_rejected,
            self._rejections,
            reinflated,
            fault_frame,
            region,
        )

    def _compass_cut(self, boxes: list[Box], compass: float) -> list[Box]:
        """The boxes' poses whose heading is within ``compass_error`` of ``compass`` (mod 2 pi)."""
        c_lo = _nextafter(compass - self._ec, -_INF)
        c_hi = _nextafter(compass + self._ec, _INF)
        return [p for b in boxes for p in compass_pieces(b, c_lo, c_hi)]

    def _slip_candidates(
        self,
        raw: list[Box],
        compass: float | None,
        view: Window | None,
    ) -> tuple[list[Box], int, bool]:
        """Recovery: the poses within ``max_slip`` of the prediction ``raw`` (before the compass)
        that the compass and the view allow (``view``: branch 0 of its windows, or None), as
        disjoint boxes (one per lattice cell).
        Without a view, only the part the compass meets (none when it misses them all); with a
        view, a compass that misses every candidate is ignored, as in :meth:`step`.
        Returns (boxes, largest number of contraction passes, hulled)."""
        cfg = self._cfg
        cap = cfg.max_boxes
        d, dt = self._slip
        grown, hulled = tidy([one_turn(inflate_box(b, d, dt)) for b in raw], cap)
        if compass is not None:
            cut = self._compass_cut(grown, compass)
            if cut:
                grown, h = tidy(cut, cap)
                hulled = hulled or h
            elif view is None:
                return [], 0, hulled  # the compass misses the slip candidates too
        if view is None:
            return grown, 0, hulled
        out, passes, h = self._contract_all(grown, view)
        return out, passes, hulled or h

    def _contract_all(self, boxes: list[Box], view: Window) -> tuple[list[Box], int, bool]:
        """Every box of ``boxes`` contracted by the view window ``view`` (:func:`view_window`):
        (the pieces, the largest number of contraction passes, whether any piece was hulled)."""
        cfg = self._cfg
        out: list[Box] = []
        passes = 0
        hulled = False
        for b in boxes:
            got, p, h = contract_view(b, view, None, self._L, self._lever, cfg.passes,
                                      self._cap)
            out.extend(got)
            if p > passes:
                passes = p
            hulled = hulled or h
        return out, passes, hulled
