"""Build the folder of the three extra real floors ``bench/real_floors.py`` reads beside
``../shared/real_floors``, from a local copy of the public repository that holds them.

    python bench/extra_floors.py MIRROR OUT

The floors are CC0 photoscans (Poly Haven's "floor_tiles_06", "floor_tiles_08" and
"square_floor_patern_01", albedo at 1k) found in the game-asset repository KILLTUBE/libwebgame_maps
at commit ``ac9e21d404635553f93097202bca30226cd26b0e`` (``textures/texturehaven_floor/``).
This repository ships none of them: ``MIRROR`` is a git directory of that repository (bare or
not) the user brought, and the images are read from the commit above with ``git show``.

Each image goes into ``OUT`` with its ``floors.json`` entry fitted by
``bench/fit_floor_lattice.py`` (a seamless texture of a known number of tiles per side; the
grout kind says which signal is a line), the declared tile size (m) and the view's pixels per
tile, and a ``SOURCES.md`` recording where each came from. Nothing is downloaded.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fit_floor_lattice as fit  # noqa: E402

REPO = "KILLTUBE/libwebgame_maps"
COMMIT = "ac9e21d404635553f93097202bca30226cd26b0e"
FOLDER = "textures/texturehaven_floor"


@dataclass(frozen=True)
class Extra:
    """One extra floor: its id, the texture's stem in ``FOLDER``, tiles per side of the
    seamless texture, the grout kind (``fit_floor_lattice.GROUT``), the tile size to declare
    (m), the view's pixels per tile, and a description."""

    id: str
    stem: str
    tiles: int
    grout: str
    tile_size_m: float
    view_period_px: float
    notes: str


EXTRAS = (
    Extra("ph_floor_tiles_06", "floor_tiles_06", 4, "edge", 0.3, 105.0,
          "marble checkerboard, dark and light tiles with a thin grout; 4 x 4 tiles"),
    Extra("ph_floor_tiles_08", "floor_tiles_08", 5, "dark", 0.3, 105.0,
          "hand-laid ceramic tiles of varied shades, dark grout that wanders; 5 x 5 tiles"),
    Extra("ph_square_floor_patern_01", "square_floor_patern_01", 16, "dark", 0.1, 64.0,
          "paver mosaic: small squares in panels, joints partly filled with light dirt; "
          "16 x 16 tiles"),
)


def build(mirror: Path, out: Path) -> list[dict]:
    """Write the three images, ``floors.json`` and ``SOURCES.md`` into ``out``; return the
    entries. Raises ``fit.FitError`` or ``OSError`` with a one-line reason."""
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for e in EXTRAS:
        src = f"{FOLDER}/{e.stem}_diff_1k.jpg"
        got = subprocess.run(["git", "--git-dir", str(mirror), "show", f"{COMMIT}:{src}"],
                             capture_output=True, check=False)
        if got.returncode != 0:
            raise OSError(f"{mirror} has no {src} at {COMMIT[:10]}: "
                          f"{got.stderr.decode(errors='replace').strip()}")
        image = out / f"{e.id}.jpg"
        image.write_bytes(got.stdout)
        meta = {"id": e.id, "file": image.name, "kind": "photo (Poly Haven photoscan albedo, "
                "seamless, CC0)", "notes": e.notes,
                "source": {"repo": REPO, "commit": COMMIT, "path": src},
                "tile_size_m": e.tile_size_m, "view_period_px": e.view_period_px}
        entries.append(fit.entry(image, fit.read_image(image), e.tiles, None, e.grout, True,
                                 None, 16, None, meta))
    (out / "floors.json").write_text(json.dumps({"floors": entries}, indent=1) + "\n",
                                     encoding="utf-8")
    lines = ["# Extra real floors (not part of the tileviz repository)", ""]
    lines += [f"- `{e.id}.jpg`: {e.notes}. {REPO} @ {COMMIT}, `{FOLDER}/{e.stem}_diff_1k.jpg` "
              "(Poly Haven, CC0)." for e in EXTRAS]
    (out / "SOURCES.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return entries


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mirror", type=Path, help=f"a git directory of {REPO}")
    ap.add_argument("out", type=Path, help="the folder to write")
    args = ap.parse_args(argv)
    try:
        for e in build(args.mirror, args.out):
            print(f"{e['id']}: lattice departure rms {e['lattice_residual_rms_px']:.2f} px, "
                  f"max {e['lattice_residual_max_px']:.2f} px")
    except (fit.FitError, OSError) as exc:
        print(f"extra_floors: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
