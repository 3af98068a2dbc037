"""Configuration dataclasses shared by the CLI, the GUI, the runner and a dataset's meta.json.

Units: metres, seconds, radians, pixels. Frames: see ``docs/dataset-format.md`` (world x east,
y north, heading counter-clockwise from +x; camera offset ``[forward, left]`` in the robot frame).

Every dataclass is frozen: change a configuration with :func:`dataclasses.replace`.
Two presets exist: ``default`` (1 m tiles, 200 px/m, 320x240) and ``seed`` (the constants of the
original implementation, ``docs/seed-code.md``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from typing import Any, Literal, get_args

Extractor = Literal["faithful", "robust"]
"""A vision extractor (:mod:`tileviz.vision`)."""
Mode = Literal["autonomous", "truth", "odometry"]
"""A localizer mode (``docs/method.md``, "Statuses and modes")."""
Setpoint = Literal["lissajous", "manual", "waypoints"]
"""A setpoint kind of the simulator's controller."""
EXTRACTORS: tuple[Extractor, ...] = get_args(Extractor)
MODES: tuple[Mode, ...] = get_args(Mode)
SETPOINTS: tuple[Setpoint, ...] = get_args(Setpoint)
FloorKind = Literal["grout", "checker"]
"""What draws a floor's lattice (``docs/dataset-format.md``, "floor"): ``grout`` lines between the
tiles, or the edges between tiles of alternating shades (``checker``, no grout)."""
FLOOR_KINDS: tuple[FloorKind, ...] = get_args(FloorKind)
SURFACES = ("procedural", "photo")
"""Tile surfaces of a simulated floor (:attr:`FloorConfig.surface`)."""
TILE_SIZE_RANGE = (0.05, 5.0)
"""Tile sizes L a simulated floor may have, metres (``serve``, ``record`` and the GUI alike)."""
PPM_RANGE = (20.0, 2000.0)
"""Resolutions a simulated camera may have, pixels per metre (``serve``, ``record``, the GUI)."""
SEED_RANGE = (0, 2**32 - 1)
"""Seeds of a simulated run (``serve``, ``record``, the GUI)."""


def finite_number(name: str, value: object) -> float:
    """``value`` as a float; ValueError naming ``name`` when it is not a finite number."""
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def _check_positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _whole(value: object) -> bool:
    """Whether ``value`` is a finite number without a fractional part (NaN and inf are not)."""
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value) and value == int(value))


def _check_nonneg(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")


@dataclass(frozen=True)
class FloorModel:
    """What is declared of a real floor's regularity (``docs/dataset-format.md``, "floor"):
    ``kind`` (:data:`FLOOR_KINDS`) and ``lattice_tolerance``, metres (>= 0): every grout line
    centre, or tile edge for ``checker``, lies within it of the ideal lattice. The default is a
    perfect grout lattice. ValueError naming the field on a bad value."""

    kind: FloorKind = "grout"
    lattice_tolerance: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in FLOOR_KINDS:
            raise ValueError(f"floor kind must be one of {', '.join(FLOOR_KINDS)}, got "
                             f"{self.kind!r}")
        if (isinstance(self.lattice_tolerance, bool)
                or not isinstance(self.lattice_tolerance, int | float)
                or not math.isfinite(self.lattice_tolerance) or self.lattice_tolerance < 0):
            raise ValueError(f"lattice_tolerance must be a finite number >= 0 (metres), got "
                             f"{self.lattice_tolerance!r}")


PERFECT_FLOOR = FloorModel()
"""A perfect grout lattice (what a dataset without a ``floor`` block declares)."""


MAX_GROUT_FRACTION = 1.0 / 8.0
"""When a floor is given another tile size, its grout is at most this fraction of the tile."""


@dataclass(frozen=True)
class FloorConfig:
    """The tiled floor. Grout line centres lie on x = kL and y = kL (world frame)."""

    tile_size: float = 1.0
    """L, the period of the tiling, metres."""
    grout_width: float = 0.012
    """Visible width of a grout line, metres."""
    tile_rgb: tuple[int, int, int] = (214, 206, 190)
    grout_rgb: tuple[int, int, int] = (92, 88, 84)
    tile_brightness_jitter: float = 0.06
    """Relative brightness variation between tiles (0 = uniform)."""
    texture_strength: float = 0.05
    """Relative amplitude of the fixed surface texture."""
    stains_per_tile: float = 0.3
    """Mean number of dark stains per tile (fixed to the floor)."""
    seed: int = 1
    """Seed of the floor's appearance (tile brightness, texture, stains)."""
    surface: str = "procedural"
    """The tiles' surface texture: ``procedural`` (mottled noise) or ``photo`` (a photograph of
    gravel, a different crop and quarter turn on each tile; ``tileviz/sim/data``)."""
    light_gradient: float = 0.0
    """Uneven lighting: relative brightness change from one side of the camera view to the
    other (a lamp off to one side of the camera), 0 = even."""
    kind: FloorKind = "grout"
    """``grout``: tiles separated by grout lines; ``checker``: tiles of ``tile_rgb`` and
    ``tile2_rgb`` alternating edge to edge, no grout (the lattice is the edges between them)."""
    lattice_tolerance: float = 0.0
    """Metres: every grout line centre (tile edge, for ``checker``) lies within this of the
    ideal lattice x = kL, y = kL (``docs/dataset-format.md``, "floor"): what a dataset declares,
    and how far the simulator lays its tiles (or panels) off the lattice: each is offset by a
    random amount up to this in x and in y (a hand-laid floor). 0: a perfect lattice."""
    tile2_rgb: tuple[int, int, int] = (60, 58, 56)
    """``checker`` only: the colour of every other tile."""
    panel_tiles: int = 0
    """A mosaic: tiles of ``tile_size`` grouped in panels of this many by this many, the panels
    separated by seams (``seam_width``, ``seam_rgb``) and laid off the lattice by up to
    ``lattice_tolerance`` as whole panels; 0: no panels."""
    seam_width: float = 0.0
    """Width of the seams between panels, metres (``panel_tiles`` > 0)."""
    seam_rgb: tuple[int, int, int] = (60, 56, 52)
    """Colour of the seams between panels."""

    @property
    def model(self) -> FloorModel:
        """What a dataset declares of this floor (kind, lattice tolerance)."""
        return FloorModel(self.kind, self.lattice_tolerance)

    def with_tile_size(self, tile_size: float) -> FloorConfig:
        """This floor with tiles of side ``tile_size`` metres; the grout keeps its width, at most
        ``tile_size`` x :data:`MAX_GROUT_FRACTION` (a narrow line on any tile). ValueError on a
        bad size."""
        return replace(self, tile_size=tile_size,
                       grout_width=min(self.grout_width, tile_size * MAX_GROUT_FRACTION))

    def __post_init__(self) -> None:
        _check_positive("tile_size", self.tile_size)
        _check_nonneg("grout_width", self.grout_width)
        if self.surface not in SURFACES:
            raise ValueError(f"surface must be one of {SURFACES}, got {self.surface!r}")
        if not isinstance(self.light_gradient, int | float) or not 0 <= self.light_gradient < 1:
            raise ValueError(f"light_gradient must be in [0, 1), got {self.light_gradient!r}")
        if self.grout_width >= self.tile_size / 2:
            raise ValueError(
                f"grout_width must be < tile_size/2, got {self.grout_width} for L={self.tile_size}"
            )
        FloorModel(self.kind, self.lattice_tolerance)  # validates both
        if self.kind == "grout" and not self.grout_width > 0:
            raise ValueError(f"kind grout needs grout_width > 0, got {self.grout_width} (tiles "
                             f"edge to edge, as the checker style draws them, are kind checker)")
        if self.lattice_tolerance >= self.tile_size / 4:
            raise ValueError(f"lattice_tolerance must be < tile_size/4, got "
                             f"{self.lattice_tolerance} for L={self.tile_size}")
        if not _whole(self.panel_tiles) or self.panel_tiles not in (0, 2, 4, 8, 16):
            raise ValueError(f"panel_tiles must be 0, 2, 4, 8 or 16, got {self.panel_tiles!r}")
        _check_nonneg("seam_width", self.seam_width)
        if self.seam_width >= self.tile_size / 2:
            raise ValueError(f"seam_width must be < tile_size/2, got {self.seam_width} for "
                             f"L={self.tile_size}")


@dataclass(frozen=True)
class CameraConfig:
    """A downward orthographic camera. Image up = robot forward, image left = robot left."""

    ppm: float = 200.0
    """Pixels per metre on the floor."""
    width: int = 320
    """Image width, pixels."""
    height: int = 240
    """Image height, pixels."""
    offset: tuple[float, float] = (0.3, 0.0)
    """Optical centre on the floor in the robot frame, [forward, left], metres (lever arm)."""
    noise_sigma: float = 3.0
    """Std dev of additive Gaussian pixel noise, gray levels (0..255)."""
    blur_sigma: float = 0.7
    """Gaussian blur, pixels (0 = none)."""
    vignetting: float = 0.15
    """Relative darkening at the image corners (0 = none)."""
    jpeg_quality: int = 0
    """JPEG re-encoding quality 1..100; 0 = no JPEG artefacts."""

    def __post_init__(self) -> None:
        _check_positive("ppm", self.ppm)
        if not _whole(self.width) or self.width < 16 or self.width > 8192:
            raise ValueError(f"image width must be an integer in [16, 8192], got {self.width!r}")
        if not _whole(self.height) or self.height < 16 or self.height > 8192:
            raise ValueError(f"image height must be an integer in [16, 8192], got {self.height!r}")
        for name in ("noise_sigma", "blur_sigma", "vignetting"):
            _check_nonneg(name, getattr(self, name))
        if not 0 <= self.jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be in [0, 100], got {self.jpeg_quality!r}")


@dataclass(frozen=True)
class NoiseConfig:
    """Bounds on the sensor errors (declared, written to datasets) and the simulated noise.

    The simulator draws each error uniformly within ``fraction`` of its bound, so the bound holds.
    """

    speed_error: float = 0.02
    """Bound on |measured speed - true speed|, m/s."""
    yaw_rate_error: float = 0.01
    """Bound on |measured yaw rate - true yaw rate|, rad/s."""
    compass_error: float = 0.02
    """Bound on the compass angular error, rad."""
    fraction: float = 1.0
    """Simulated errors are drawn uniformly in +-fraction*bound (1.0 = use the whole bound)."""

    def __post_init__(self) -> None:
        for name in ("speed_error", "yaw_rate_error", "compass_error", "fraction"):
            _check_nonneg(name, getattr(self, name))


@dataclass(frozen=True)
class VisionConfig:
    """Image pipeline constants. Defaults are the original implementation's (report ch. 4)."""

    extractor: Extractor = "robust"
    """``faithful`` (report chapter 4, corrected) or ``robust`` (checks, refuses bad frames)."""
    laplacian_ksize: int = 1
    canny_low: float = 50.0
    canny_high: float = 255.0
    canny_aperture: int = 3
    close_kernel: int = 1
    dilate_kernel: int = 3
    dilate_iterations: int = 1
    hough_rho: float = 1.0
    hough_theta: float = math.pi / 180
    hough_threshold: int = 60
    hough_min_line_length: float = 100.0
    hough_max_line_gap: float = 50.0
    l1_threshold: float = 0.15
    """Outlier filter on (cos 4a, sin 4a): keep segments with L1 distance to the median < this."""
    bag_threshold: float = 0.2
    """|cos| (resp. |sin|) below this after de-rotation puts a segment in the vertical
    (resp. horizontal) bag."""
    min_segments: int = 2
    """Continue only with at least this many good segments."""
    position_error_px: float = 3.0
    """Bound on the error of y1, y2, in pixels (converted with ppm): the faithful extractor
    declares this bound for every view. The robust extractor declares each view's own bound
    from the evidence in that image (docs/vision.md), scales its consistency checks with the
    smaller of this and 2 px, and refuses a view whose bound exceeds the larger of this and
    its own limit (``RobustSettings.bound.max_px``, 5 px: ``imprecise``)."""
    heading_error: float = 0.025
    """Bound on the error of y3, rad: the faithful extractor's declared bound; for the robust
    extractor as ``position_error_px`` (its own limit ``RobustSettings.bound.max_rad``,
    0.05 rad)."""

    def __post_init__(self) -> None:
        if self.extractor not in EXTRACTORS:
            raise ValueError(f"extractor must be one of {EXTRACTORS}, got {self.extractor!r}")
        _check_positive("position_error_px", self.position_error_px)
        _check_positive("heading_error", self.heading_error)


@dataclass(frozen=True)
class LocalizerConfig:
    """The interval localizer."""

    mode: Mode = "autonomous"
    """``autonomous`` (only the initial pose known), ``truth`` (reset to the inflated truth every
    frame, report 7.1) or ``odometry`` (prediction only, report Fig 7.1)."""
    max_boxes: int = 16
    """Cap on the number of disjoint boxes; past it the set is replaced by its hull."""
    passes: int = 3
    """Maximum contraction passes (stops earlier at a fixpoint)."""
    truth_inflation: tuple[float, float, float] = (0.3, 0.3, 0.2)
    """Truth mode: half-widths (m, m, rad) added around the true pose every frame."""
    max_rejections: int = 20
    """Consecutive rejected observations after which the status becomes ``lost``."""
    max_slip: tuple[float, float] = (0.0, 0.0)
    """Recovery (docs/method.md, "Recovery"): the largest pose error (metres, in x and in
    y; radians, in heading) that an odometry fault (wheel slip beyond the declared bounds, an
    outlier reading, a small push) may have added to the prediction by the frame where the
    localizer notices it. On a rejected view (or a compass that misses the set) the set then also
    keeps the poses within this of the prediction that the view and the compass allow.
    ``(0, 0)``: no recovery (a rejected view is ignored and the prediction kept)."""
    slip_window: int = 40
    """Recovery only: for this many frames after the localizer noticed an inconsistency, every
    view contracts the prediction inflated by ``max_slip`` (a slip still going on is followed
    rather than lost again); 0 = only the frame that noticed it."""

    fault_speed: float = 0.2
    """Fault model (``docs/faults.md``): how much faster, in m/s, a fault (a wheel slip, a push)
    may move the robot than the odometry and its ``speed_error`` allow. With ``fault_speed`` or
    ``fault_yaw_rate`` > 0 the localizer also keeps the fault set: every pose reachable under the
    bounds widened by the fault model, contracted by every view; when a view or the compass
    rejects the set, the localizer takes the fault set's contraction instead (it tracks through
    the slip). 0 and 0: no fault model. A ``max_slip`` recovery (above, not both 0) replaces the
    fault model. The default (0.2 m/s, 0.1 rad/s): ``docs/faults.md``, "The default fault
    model"."""
    fault_yaw_rate: float = 0.1
    """Fault model: how much faster, in rad/s, a fault may turn the robot than the odometry and
    its ``yaw_rate_error`` allow."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")
        _check_nonneg("fault_speed", self.fault_speed)
        _check_nonneg("fault_yaw_rate", self.fault_yaw_rate)
        if not isinstance(self.max_slip, tuple | list) or len(self.max_slip) != 2:
            raise ValueError(f"max_slip must be (metres, radians), got {self.max_slip!r}")
        _check_nonneg("max_slip[0]", self.max_slip[0])
        _check_nonneg("max_slip[1]", self.max_slip[1])
        if not _whole(self.max_boxes) or self.max_boxes < 1:
            raise ValueError(f"max_boxes must be an integer >= 1, got {self.max_boxes!r}")
        if not _whole(self.passes) or self.passes < 1:
            raise ValueError(f"passes must be an integer >= 1, got {self.passes!r}")
        if isinstance(self.slip_window, bool) or not isinstance(self.slip_window, int) or (
                self.slip_window < 0):
            raise ValueError(f"slip_window must be an integer >= 0, got {self.slip_window!r}")
        if (isinstance(self.max_rejections, bool) or not isinstance(self.max_rejections, int)
                or self.max_rejections < 1):
            raise ValueError(f"max_rejections must be an integer >= 1, got {self.max_rejections!r}")
        if not isinstance(self.truth_inflation, tuple | list) or len(self.truth_inflation) != 3:
            raise ValueError(f"truth_inflation must be (x, y, theta), got {self.truth_inflation!r}")
        for i, v in enumerate(self.truth_inflation):
            _check_nonneg(f"truth_inflation[{i}]", v)


@dataclass(frozen=True)
class SimConfig:
    """The pymunk simulation and its setpoint."""

    dt: float = 0.05
    """Frame period (simulation step between frames), s."""
    seed: int = 0
    """Seed of the sensor noise (and anything else random in the run)."""
    setpoint: str = "lissajous"
    lissajous_amplitude: float = 4.0
    """A in x = A cos(w t + pi/2), y = A sin(2 (w t + pi/2)), metres."""
    lissajous_omega: float = 0.04
    """w, rad/s."""
    waypoints: tuple[tuple[float, float], ...] = ((2.0, 0.0), (2.0, 2.0), (-2.0, 2.0), (-2.0, 0.0))
    manual_target: tuple[float, float] = (1.0, 1.0)
    room_half_size: float = 6.0
    """Half side of the square room, metres; walls at +-this when ``walls``."""
    walls: bool = False
    obstacles: tuple[tuple[float, float, float], ...] = ()
    """Round obstacles (x, y, radius), metres."""
    max_wheel_speed: float = 0.8
    """Wheel speed saturation, m/s."""
    wheel_base: float = 0.4
    """Distance between the wheels, metres."""
    initial_pose: tuple[float, float, float] = (0.0, 0.0, math.atan2(-2.0, -1.0))
    """Pose at t = 0 (x, y, theta); the default is the Lissajous start (the curve passes through
    the origin at t = 0 heading along (-1, -2))."""
    initial_pose_error: tuple[float, float, float] = (0.05, 0.05, 0.02)
    """The true start lies within initial_pose +- these (m, m, rad)."""

    def __post_init__(self) -> None:
        _check_positive("dt", self.dt)
        if self.setpoint not in SETPOINTS:
            raise ValueError(f"setpoint must be one of {SETPOINTS}, got {self.setpoint!r}")
        _check_positive("lissajous_amplitude", self.lissajous_amplitude)
        _check_nonneg("lissajous_omega", self.lissajous_omega)
        _check_positive("room_half_size", self.room_half_size)
        _check_positive("max_wheel_speed", self.max_wheel_speed)
        _check_positive("wheel_base", self.wheel_base)
        for i, v in enumerate(self.initial_pose_error):
            _check_nonneg(f"initial_pose_error[{i}]", v)


@dataclass(frozen=True)
class Config:
    """Everything a run needs."""

    floor: FloorConfig = field(default_factory=FloorConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    vision: VisionConfig = field(default_factory=VisionConfig)
    localizer: LocalizerConfig = field(default_factory=LocalizerConfig)
    sim: SimConfig = field(default_factory=SimConfig)

    @property
    def tile_size(self) -> float:
        """L, metres."""
        return self.floor.tile_size

    @property
    def position_error(self) -> float:
        """Declared bound on the error of y1, y2, metres."""
        return self.vision.position_error_px / self.camera.ppm

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able nested dict."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Config:
        """Inverse of :meth:`to_dict`; unknown keys raise ValueError naming them."""
        return _from_dict(cls, d, "config")


def _from_dict(cls: type, d: dict[str, Any], where: str) -> Any:
    if not isinstance(d, dict):
        raise ValueError(f"{where} must be an object, got {type(d).__name__}")
    names = {f.name for f in fields(cls)}
    defaults = cls()
    kwargs: dict[str, Any] = {}
    for key, value in d.items():
        if key not in names:
            raise ValueError(f"unknown option {where}.{key}")
        default = getattr(defaults, key)
        if is_dataclass(default):
            kwargs[key] = _from_dict(type(default), value, f"{where}.{key}")
        elif isinstance(default, tuple):
            kwargs[key] = _to_tuple(value)
        else:
            kwargs[key] = value
    try:
        return cls(**kwargs)
    except TypeError as e:
        raise ValueError(f"bad {where}: {e}") from None


def _to_tuple(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return tuple(_to_tuple(v) for v in value)
    return value


PRESET_VISION = VisionConfig(position_error_px=1.5, heading_error=0.0065)
"""Vision bounds of both presets' cameras (noise 3 gray levels, blur 0.7 px, no JPEG): the
faithful extractor declares them for every view; the robust extractor declares each view's own
bound (docs/vision.md), within these on the presets' clean views (``tests/test_preset_bounds.py``;
the figures: ``bench/preset_bounds.py``, docs/figures.md), and its checks scale with them."""


FLOOR_STYLES: dict[str, dict[str, Any]] = {
    "default": {},
    "light_grout": {"tile_rgb": (96, 92, 86), "grout_rgb": (228, 226, 220)},
    "wide_grout": {"grout_width": 0.05},
    "photo": {"surface": "photo", "texture_strength": 0.15, "stains_per_tile": 0.0,
              "grout_rgb": (40, 38, 36)},
    "gradient": {"light_gradient": 0.5},
    "checker": {"kind": "checker", "grout_width": 0.0, "tile_rgb": (222, 216, 204),
                "tile2_rgb": (52, 50, 48), "stains_per_tile": 0.1},
    "hand_laid": {"grout_width": 0.014, "lattice_tolerance": 0.005},
    "mosaic": {"panel_tiles": 4, "seam_width": 0.03, "lattice_tolerance": 0.008},
    "faint_colour": {"tile_rgb": (150, 110, 80), "grout_rgb": (172, 92, 72),
                     "grout_width": 0.006, "texture_strength": 0.03},
}
"""Floor styles (``record --floor-style``, the demo's floor settings): changes to a FloorConfig.
``light_grout``: grout lighter than the tiles; ``wide_grout``: 5 cm grout bands (at most an
eighth of the tile, see :func:`floor_style`); ``photo``: a photograph of gravel on the tiles;
``gradient``: uneven lighting across the camera view; ``checker``: light and dark tiles edge to
edge, no grout; ``hand_laid``: every tile laid up to 5 mm off the lattice; ``mosaic``: the tiles
in panels of 4 x 4 with 3 cm seams, each panel laid up to 8 mm off the lattice; ``faint_colour``:
reddish grout on brown tiles, nearly as light (it differs more in hue than in gray). Lengths
scale with the tile as :func:`floor_style` says."""


def floor_style(floor: FloorConfig, name: str) -> FloorConfig:
    """``floor`` in the style ``name`` (a key of :data:`FLOOR_STYLES`), its tile size and seed
    kept; ValueError naming the style when unknown."""
    if name not in FLOOR_STYLES:
        raise ValueError(f"unknown floor style {name!r}; choose from {', '.join(FLOOR_STYLES)}")
    base = FloorConfig(tile_size=floor.tile_size, seed=floor.seed,
                       grout_width=min(FloorConfig().grout_width, floor.tile_size / 8))
    values = dict(FLOOR_STYLES[name])
    for key, most in (("grout_width", 1 / 8), ("seam_width", 1 / 8),
                      ("lattice_tolerance", 1 / 40)):
        if key in values:
            values[key] = min(values[key], floor.tile_size * most)
    return replace(base, **values)


def with_floor_style(cfg: Config, name: str) -> Config:
    """``cfg`` with its floor in the style ``name`` (:func:`floor_style`). A style other than
    ``default`` also takes the general vision limits (``VisionConfig`` defaults, the extractor
    kept): the presets' tighter limits hold for the presets' own floor."""
    out = replace(cfg, floor=floor_style(cfg.floor, name))
    if name != "default":
        out = replace(out, vision=replace(VisionConfig(), extractor=cfg.vision.extractor))
    return out


def preset(name: str) -> Config:
    """Return a named preset: ``default`` or ``seed``."""
    if name == "default":
        return Config(vision=PRESET_VISION)
    if name == "seed":
        # Constants of the original implementation (docs/seed-code.md).
        return Config(
            floor=FloorConfig(tile_size=0.166, grout_width=0.004),
            camera=CameraConfig(ppm=620.48, width=256, height=384, offset=(0.875, 0.0)),
            noise=NoiseConfig(speed_error=0.02, yaw_rate_error=0.01, compass_error=0.02),
            # the original image constants; the robust extractor keeps the guarantee (the
            # faithful one, selectable, returns views outside their bound now and then)
            vision=PRESET_VISION,
            sim=SimConfig(
                dt=0.05,
                lissajous_amplitude=10.0,
                lissajous_omega=0.01,
                room_half_size=12.0,
                initial_pose=(0.0, 0.0, math.atan2(-2.0, -1.0)),
            ),
        )
    raise ValueError(f"unknown preset {name!r}; choose 'default' or 'seed'")


PRESETS = ("default", "seed")


def with_overrides(cfg: Config, **sections: dict[str, Any]) -> Config:
    """Return ``cfg`` with some fields of some sections replaced, e.g.
    ``with_overrides(cfg, camera={"ppm": 300})``. Raises ValueError on unknown names."""
    out = cfg
    for section, values in sections.items():
        if not hasattr(out, section):
            raise ValueError(f"unknown config section {section!r}")
        sub = getattr(out, section)
        names = {f.name for f in fields(sub)}
        for k in values:
            if k not in names:
                raise ValueError(f"unknown option {section}.{k}")
        out = replace(out, **{section: replace(sub, **values)})
    return out
