"""The pure core: interval arithmetic, the tile lattice, the localizer and the estimator
interface. No I/O, no viser, no pymunk."""
