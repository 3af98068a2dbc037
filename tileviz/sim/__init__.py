"""The simulator: pymunk world, setpoints, controller, bounded sensors, the frame source, and the
downward camera (:mod:`tileviz.sim.camera`).

This package module imports nothing on purpose: ``tileviz.sim.camera`` (pure numpy/OpenCV) must be
importable without pymunk, so vision code and tests never pull the physics engine in.
"""
