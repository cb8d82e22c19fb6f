"""The detections drawn over their image (synptv ptv --overlay)."""

import numpy as np

from ptv.detect.detections import Detections
from validation.report.overlay import CIRCLE_BGR, MIN_RADIUS_PX, overlay_image


def test_each_detection_is_circled_where_it_is():
    image = np.random.default_rng(0).normal(100.0, 5.0, (120, 200))
    centres = np.array([[60.0, 70.0], [150.0, 90.0]])
    found = Detections(
        xy=centres,
        intensity=np.ones(2),
        peak=np.ones(2),
        size=np.array([4, 4]),
        flags=np.zeros(2, np.uint8),
        shape=image.shape,
    )
    picture = overlay_image(image, found, "frame.tif")
    assert picture.shape == (120, 200, 3) and picture.dtype == np.uint8
    red = np.all(picture == CIRCLE_BGR, axis=2)
    rows, cols = np.nonzero(red)
    # Every circle pixel lies on a ring of radius max(4, √(size/π) + 2) ≈ 4.3 px round
    # one of the centres (one-pixel line, rounded to whole pixels).
    distance = np.min(
        np.hypot(cols[:, None] - centres[:, 0], rows[:, None] - centres[:, 1]), axis=1
    )
    assert len(rows) > 2 * 2 * np.pi * MIN_RADIUS_PX * 0.5
    assert np.all(np.abs(distance - 4.0) <= 1.5)
    for x, y in centres:  # both circled
        assert np.any(np.hypot(cols - x, rows - y) < 6)
