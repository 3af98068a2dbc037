"""The tile observation model and its (corrected) equivalence.

Frames (``docs/dataset-format.md``): world metres, x east, y north; heading theta
counter-clockwise from +x (rad); grout line centres on x = kL and y = kL; the camera's optical
centre is c = (x, y) + R(theta) @ (forward, left).

The floor's line pattern is invariant under the translations L Z^2 and under the quarter turns
R(m pi/2) about a line crossing, and under nothing else that keeps orientation. So the view
depends on the camera pose (c, theta) only up to those symmetries, and (docs/method.md):

    y = (y1, y2, y3),  y1, y2 in [0, L),  y3 in [-pi/4, pi/4),
    (c_x, c_y) == R(m pi/2) (y1, y2)  (mod L)  and  theta == y3 + m pi/2  (mod 2 pi)

for the m in {0, 1, 2, 3} with theta - m pi/2 in [-pi/4, pi/4) (mod 2 pi). Two parameter vectors
describe the same view iff they differ by such a symmetry (:func:`equivalent_parameters`). The
original report's Theorem 1 (eq. 3.9/3.11) instead pairs a quarter turn with a swap (y2, y1)
without the sign change of R(pi/2) (y1, y2) = (-y2, y1), and treats a half turn as the identity
(theta == y3 mod pi with the same (y1, y2)); both are wrong in general (see
``tests/test_tiles.py``, which renders the floor at such poses).
"""

from __future__ import annotations

import math

from tileviz.core.constants import HALF_PI, TWO_PI
from tileviz.types import Observation, Pose

__all__ = [
    "camera_centre",
    "equivalence_residuals",
    "equivalent_parameters",
    "equivalent_pose",
    "equivalent_poses",
    "observe",
    "quarter_turn",
    "quarter_turns",
]



def quarter_turn(m: int, a: float, b: float) -> tuple[float, float]:
    """R(m pi/2) @ (a, b), exactly (only sign changes and swaps); any integer m."""
    m &= 3
    if m == 0:
        return (a, b)
    if m == 1:
        return (-b, a)
    if m == 2:
        return (-a, -b)
    return (b, -a)


def quarter_turns(theta: float) -> int:
    """The m in {0, 1, 2, 3} with theta - m pi/2 in [-pi/4, pi/4) (mod 2 pi)."""
    return math.floor((theta + 0.25 * math.pi) / HALF_PI) & 3


def camera_centre(pose: Pose, offset: tuple[float, float]) -> tuple[float, float]:
    """The camera's optical centre on the floor, c = (x, y) + R(theta) @ (forward, left), metres,
    world frame (docs/dataset-format.md)."""
    f, left = offset
    ct = math.cos(pose.theta)
    st = math.sin(pose.theta)
    return (pose.x + f * ct - left * st, pose.y + f * st + left * ct)


def _mod(v: float, period: float) -> float:
    """v mod period in [0, period) (float % can round up to period itself)."""
    r = v % period
    return 0.0 if r >= period else r


def observe(
    pose: Pose, tile_size: float, offset: tuple[float, float]
) -> tuple[float, float, float]:
    """The exact observation (y1, y2, y3) of ``pose`` (docs/method.md).

    y3 = theta - m pi/2 in [-pi/4, pi/4) and (y1, y2) = R(-m pi/2) c mod L in [0, L)^2, where m is
    the number of quarter turns in theta and c the camera centre. Metres, metres, radians.
    """
    if not tile_size > 0:
        raise ValueError(f"tile_size must be > 0, got {tile_size!r}")
    cx, cy = camera_centre(pose, offset)
    m = quarter_turns(pose.theta)
    y3 = math.remainder(pose.theta - m * HALF_PI, TWO_PI)
    if y3 >= 0.25 * math.pi:  # rounding at the branch edge
        y3 -= HALF_PI
        m = (m + 1) & 3
    elif y3 < -0.25 * math.pi:
        y3 += HALF_PI
        m = (m - 1) & 3
    u1, u2 = quarter_turn(-m, cx, cy)
    return (_mod(u1, tile_size), _mod(u2, tile_size), y3)


def equivalent_parameters(
    y: tuple[float, float, float], tile_size: float
) -> list[tuple[float, float, float]]:
    """The four parameter vectors z ~ y, for m = 0, 1, 2, 3:
    (z1, z2) = R(m pi/2) (y1, y2) mod L (in [0, L)) and z3 = y3 + m pi/2 (not wrapped).

    Two vectors describe the same view iff one is in the other's list (up to z3 mod 2 pi)."""
    y1, y2, y3 = y
    out = []
    for m in range(4):
        z1, z2 = quarter_turn(m, y1, y2)
        out.append((_mod(z1, tile_size), _mod(z2, tile_size), y3 + m * HALF_PI))
    return out


def equivalent_pose(
    pose: Pose,
    m: int,
    tile_size: float,
    offset: tuple[float, float],
    shift: tuple[int, int] = (0, 0),
) -> Pose:
    """The pose whose camera sees exactly what ``pose``'s camera sees, turned by m quarter turns:
    camera centre c' = R(m pi/2) c + L * shift, heading theta' = theta + m pi/2, and the robot
    point put back behind it through the lever arm, (x', y') = c' - R(theta') @ offset."""
    cx, cy = camera_centre(pose, offset)
    ax, ay = quarter_turn(m, cx, cy)
    ax += tile_size * shift[0]
    ay += tile_size * shift[1]
    theta = pose.theta + m * HALF_PI
    f, left = offset
    ct = math.cos(theta)
    st = math.sin(theta)
    return Pose(ax - (f * ct - left * st), ay - (f * st + left * ct), theta)


def equivalent_poses(pose: Pose, tile_size: float, offset: tuple[float, float]) -> list[Pose]:
    """:func:`equivalent_pose` for m = 0, 1, 2, 3 (no lattice shift)."""
    return [equivalent_pose(pose, m, tile_size, offset) for m in range(4)]


def equivalence_residuals(
    truth: Pose, obs: Observation, tile_size: float, offset: tuple[float, float]
) -> tuple[float, float, float, float, float, float]:
    """The six equivalence residuals of report table 6.1 (the ``--output-file`` CSV), with the
    corrected signs; all six are dimensionless in [-1, 1].

    Let c be the true camera centre and d = theta - y3.

    - "direct" family (report: sin, sin, sin): take m in {0, 2} whose heading branch d - m pi/2
      is closest to 0 mod 2 pi, u = R(-m pi/2) c, and
      r1 = sin(pi (u1 - y1) / L), r2 = sin(pi (u2 - y2) / L), r3 = sin(d).
    - "swapped" family (report: sin, sin, cos): the same with m in {1, 3}, giving r4, r5, and
      r6 = cos(d).

    r3 and r6 are the original's. When the observation is right (the corrected equivalence holds
    for some m) the triple of that m's family is zero up to rounding; the original used
    u = c (m = 0) for the first triple and u = (c_y, c_x) (a swap with no sign) for the second,
    which is zero only by accident for m = 1, 2, 3. A tie (|d - m pi/2| equal for both m of a
    family) picks the smaller m.
    """
    cx, cy = camera_centre(truth, offset)
    d = truth.theta - obs.y3
    k = math.pi / tile_size
    out: list[float] = []
    for family in ((0, 2), (1, 3)):
        m = min(family, key=lambda j: abs(math.remainder(d - j * HALF_PI, TWO_PI)))
        u1, u2 = quarter_turn(-m, cx, cy)
        out.append(math.sin(k * (u1 - obs.y1)))
        out.append(math.sin(k * (u2 - obs.y2)))
        out.append(math.sin(d) if m in (0, 2) else math.cos(d))
    return (out[0], out[1], out[2], out[3], out[4], out[5])
