"""The robust extractor: sub-pixel lattice parameters, and a refusal when the view is doubtful.

Modules, one per job: :mod:`.settings` (every threshold, by stage), :mod:`.checks` (every
check: id, limit, the settings it reads; the list of check ids is its docstring),
:mod:`.state` (the view's immutable data and one reading's working state), :mod:`.readings`
(the candidate readings tried in order by one loop, and the function that reads a view for
one reading), :mod:`.statistics` (step 1), :mod:`.heading` (step 2), :mod:`.projection` (step
3), :mod:`.profiles` (step 4), :mod:`.periodic` (step 4's tile period), :mod:`.fit` (step 5
and the line checks), :mod:`.lattice` (spacing, the observation), :mod:`.bound` (the view's
error bound), :mod:`.foreign` (the last checks; :mod:`.grout_levels` reads the grout where an
edge meets it) and :mod:`.extractor` (the entry point, the decision, the result and the stage
images); the compiled loops are in :mod:`.kernel`, :mod:`.projection_kernel`,
:mod:`.heading_kernel`, :mod:`.fit_kernel`, :mod:`.lattice_kernel` and :mod:`.foreign_kernel`.
The result carries the decision path (:class:`~tileviz.vision.decision.Decision`: every check
with its value and limit, the readings tried, the refusing check).

How it measures (vectorised numpy/OpenCV; timings in ``bench/bench_vision.py``):

1. Gray statistics: a constant image, or one with many saturated pixels in large patches
   (glare; a light texture's scattered saturated specks are not), is refused.
2. Scharr gradients; the heading modulo pi/2 from the gradient directions of the strongest
   fifth of the gradients (every other row and column; a weighted histogram of 4 phi, its peak,
   then the weighted circular mean of the pixels near the peak: the report's
   (cos 4a, sin 4a) of eq. 4.4 applied per pixel).
3. One affine warp turns the image by that heading so that family-1 grout lines become rows and
   family-2 lines columns (:func:`~tileviz.vision.geometry.family_normals`). Row (column) means
   are the gray profile across every line of a family, averaged over the whole line.
4. Dips of a profile are the line candidates. Each is then measured in four equal parts of the
   stretch of its line that every sample of its window sees (sums from the integral image of
   the warp, so that the samples of a part all average the same stretch of floor): its
   position is the midpoint of the dip's two 50 % crossings, each side's darkness taken
   against that side's own plateau level and depth (a brighter tile on one side, texture or a
   slope of the light beside the grout do not pull it; the centroid of the darkness, re-centred
   three times, only seeds the search); the 25 and 75 % midpoints and the part's roughness give
   the part its own error bound; its depth, contrast (depth / level), half-depth width, 20-80 %
   edge rise and the step between its two sides are measured too. Dips much wider than the
   strong ones (a shadow, a stain) are not lines, nor are dips off the tile period that are
   weak beside the lattice's lines (a texture's lines inside the tiles, :mod:`.periodic`).
5. A least-squares fit over every line's part positions gives the residual tilt of the warp
   (one slope shared by all lines, one intercept per line): the heading correction, each
   line's offset at the image centre, and standard errors from the scatter of the parts. A
   large correction redoes the warp. Lines that fail the line checks are read again at other
   headings and with the other polarity, and a view refused after its lines were found not
   straight is read again leaving out the one part that alone kept them from straight
   (:func:`.fit.drop_stray_part`: a texture's dip measured beside the grout): the plan of
   :mod:`.readings`.
6. Checks, in order; the first that fails is the ``reason``:
   ``constant image``, ``glare``, ``no lines``, ``low contrast``, ``one family``, ``blurred``
   (edges too soft), ``step edge`` (a line with a different level on each side),
   ``inconsistent angle`` (a line not straight, or the two families not perpendicular within
   their errors), ``foreign line`` (a line unlike the others in width or contrast: grout lines
   share both; lighter grout may instead agree in depth over the grout's own level),
   ``inconsistent spacing`` (line offsets not multiples of L apart, or a well-visible
   lattice line missing), ``too few segments`` (too little line length per
   family), ``imprecise`` (the view's own bound, :mod:`.bound`, exceeds the largest a view
   may declare: ``RobustSettings.bound.max_px`` / ``max_rad``, 5 px / 0.05 rad, or the
   configured ``VisionConfig`` bounds when larger), then
   ``foreign line`` / ``step edge`` again for a long straight edge that is not on the lattice
   (a cable; a box or shadow edge), found by a probabilistic Hough transform on the Canny edges
   that the predicted grout lines do not explain.

Known limit: a straight dark object lying exactly along the grout direction (within about
0.2 deg), as wide and as dark as the grout, with no real grout line of that family in view,
cannot be told from grout by a single image; the fault study shows how rare that is.

The observation carries the view's own bound (:mod:`.bound`, px / ppm and rad). The
consistency checks work at the smaller of the configured bounds (``VisionConfig.position_error_px``,
``VisionConfig.heading_error``) and the check scales of :class:`RobustSettings` (2 px, 0.02 rad):
the configured defaults (3 px, 0.025 rad) keep a margin over the largest errors the accuracy
study saw among accepted frames (``bench/accuracy_study.py``), and a tighter configured bound
tightens the checks.
"""


from __future__ import annotations

from tileviz.vision.robust.extractor import extract_robust
from tileviz.vision.robust.lattice import clip_line, normalise
from tileviz.vision.robust.settings import DEFAULT_SETTINGS, RobustSettings

__all__ = ["DEFAULT_SETTINGS", "RobustSettings", "clip_line", "extract_robust", "normalise"]
