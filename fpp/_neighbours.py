"""Counts and extremes over each pixel's 8 neighbours (OpenCV filters; the outside of the image never counts), shared
by the depth-edge tests."""
from __future__ import annotations

import cv2
import numpy as np

# the 8 neighbours of a pixel, as an OpenCV kernel (the centre left out)
_NEIGHBOURS = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]], dtype=np.uint8)


def neighbour_max(values: np.ndarray) -> np.ndarray:
    """The largest of each pixel's 8 neighbours (float32; -inf outside the image)."""
    return cv2.dilate(np.asarray(values, dtype=np.float32), _NEIGHBOURS, borderType=cv2.BORDER_CONSTANT,
                      borderValue=-np.inf)


def neighbour_count(mask: np.ndarray) -> np.ndarray:
    """How many of each pixel's 8 neighbours are set (outside the image: none)."""
    return cv2.filter2D(mask.astype(np.uint8), cv2.CV_16S, _NEIGHBOURS.astype(np.float32),
                        borderType=cv2.BORDER_CONSTANT)
