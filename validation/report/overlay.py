"""The detections drawn over the images they came from (``synptv ptv --overlay``), so
that a user can judge the detection settings by eye, without Python.

Each picture is one camera's frame at its own size: the grey levels stretched between
their 0.5th and 99.9th percentiles (a dim recording stays visible), every detection a
circle of about its size, and in the corner the image's name and the count.
"""

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from ptv.detect.detections import Detections

#: Circle and text colours (BGR), and the smallest circle radius, px.
CIRCLE_BGR = (0, 0, 255)
TEXT_BGR = (0, 255, 255)
MIN_RADIUS_PX = 4


def overlay_image(image: np.ndarray, found: Detections, title: str) -> np.ndarray:
    """The image as 8-bit colour with its detections circled.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        The recorded grey levels, DN.
    found : Detections
        Its N detections (centres px, sizes px).
    title : str
        Written in the top-left corner with the count.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        BGR picture.
    """
    grey = np.asarray(image, dtype=np.float64)
    low, high = np.percentile(grey, [0.5, 99.9])
    scaled = np.clip((grey - low) / max(high - low, 1e-12), 0.0, 1.0)
    picture = cv2.cvtColor(np.round(255 * scaled).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    radii = np.maximum(MIN_RADIUS_PX, np.sqrt(found.size / np.pi) + 2.0)
    for (x, y), r in zip(found.xy, radii, strict=True):
        centre = (round(float(x)), round(float(y)))
        cv2.circle(picture, centre, round(float(r)), CIRCLE_BGR, 1, cv2.LINE_8)
    scale = max(0.5, grey.shape[1] / 1600)
    text = f"{title}: {len(found)} detections"
    corner = (10, int(30 * scale))
    thickness = max(1, int(2 * scale))
    font = cv2.FONT_HERSHEY_SIMPLEX
    (width, height), depth = cv2.getTextSize(text, font, scale, thickness)
    top_left = (corner[0] - 4, corner[1] - height - 4)
    bottom_right = (corner[0] + width + 4, corner[1] + depth + 4)
    cv2.rectangle(picture, top_left, bottom_right, (0, 0, 0), cv2.FILLED)  # readable text
    cv2.putText(picture, text, corner, font, scale, TEXT_BGR, thickness, cv2.LINE_AA)
    return picture


def save_overlays(detector, snapshots: Sequence[int], out: Path) -> list[Path]:
    """Frames a and b of ``snapshots`` at the first Δt, one PNG per camera and frame,
    with their detections: ``out/overlay_<camera>_<m>_<a|b>.png``.

    Parameters
    ----------
    detector : ptv.detect.frames.ImageDetector
        The dataset and the detection settings of the run.
    snapshots : sequence of int
        Snapshot numbers m at Δt_0, each below the dataset's count there.
    out : Path
        An existing folder.

    Returns
    -------
    list of Path
        The pictures written.
    """
    written = []
    for m in snapshots:
        for frame in "ab":
            found = detector.detect(0, m, frame)
            for camera, detections in zip(detector.cameras, found, strict=True):
                image = detector.dataset.read_frame(0, camera, m, frame)
                name = detector.dataset.frame_path(0, camera, m, frame).name
                path = out / f"overlay_{camera}_{m:06d}_{frame}.png"
                if not cv2.imwrite(str(path), overlay_image(image, detections, name)):
                    raise OSError(f"{path}: could not be written")
                written.append(path)
    return written
