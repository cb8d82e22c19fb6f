"""The PTV stack: detection, calibration, triangulation, matching, tracking, statistics.

``ptv`` never imports ``simulator``: it sees only what a real experiment gives
(images, the nominal target description and the Δt values).
"""
