"""What the cloud node packs into each point, and the per-scan images it waits for (pure logic, no sockets).

A point of the organized cloud carries, as float32 fields in this order (:data:`FIELDS`):

========================= =============================================================================
field                     meaning
========================= =============================================================================
``x, y, z``               metres in the camera optical frame; NaN where the pixel has no point
``intensity``             the surface's texture in camera DN (:mod:`dptpu.fpp.texture`: white - black
                          frame, or the mean intensity ``A`` of Eq. (2)), from the phase node's
                          ``/scanner/texture``; NaN when the scan's texture image was not seen
``modulation``            the fringe modulation ``B`` (DN) of the unwrapped frequency, from the unwrap
                          node's ``/scanner/intensity``; NaN when not seen
``confidence``            the unwrapping confidence in [0, 1] (``AbsolutePhase.reliability``), 0 where
                          there is no point
``normal_x/y/z``          the unit surface normal from the organized neighbours, toward the camera
                          (:func:`dptpu.fpp.organized_normals.organized_normals`); NaN where none. Only
                          with the node's ``normals`` parameter (default true)
========================= =============================================================================

The names follow PCL's (``normal_x``, ``intensity``), so ``pcl::PointXYZINormal``-style consumers and RViz's
PointCloud2 display find them.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np

from dptpu.messages import Image

__all__ = ["FIELDS", "NORMAL_FIELDS", "SideImages", "cloud_fields"]

NORMAL_FIELDS = ("normal_x", "normal_y", "normal_z")
#: Every field of the cloud, in order (the normals only with ``normals: true``).
FIELDS = ("x", "y", "z", "intensity", "modulation", "confidence", *NORMAL_FIELDS)


def cloud_fields(normals: bool) -> tuple[str, ...]:
    """The cloud's field names, in order: :data:`FIELDS`, without the normals when ``normals`` is false."""
    return FIELDS if normals else FIELDS[:-len(NORMAL_FIELDS)]


class SideImages:
    """The last few 32FC1 images of each side topic (texture, modulation) of the scans, by stamp.

    A scan's ``AbsolutePhase`` and its side images travel on separate topics and race inside the cloud process;
    the node keeps the images here and triangulates a scan once every side topic that has a publisher delivered
    the image of the scan's stamp (or the wait ran out).

    Parameters
    ----------
    names : sequence of str
        The side topics' short names, e.g. ``("texture", "modulation")``.
    kept : int
        Images kept per topic (the oldest is dropped first).
    """

    def __init__(self, names, kept: int):
        self.kept = int(kept)
        self._images: dict[str, OrderedDict[int, Image]] = {name: OrderedDict() for name in names}

    def add(self, name: str, msg: Image) -> int:
        """Keep ``msg`` of topic ``name``; returns its stamp in ns."""
        images = self._images[name]
        stamp_ns = msg.header.stamp.to_ns()
        images[stamp_ns] = msg
        while len(images) > self.kept:
            images.popitem(last=False)
        return stamp_ns

    def has(self, name: str, stamp_ns: int) -> bool:
        return stamp_ns in self._images[name]

    def take(self, name: str, stamp_ns: int, shape: tuple[int, int]) -> np.ndarray | None:
        """The (H, W) float32 view of topic ``name``'s image of ``stamp_ns`` (removed from the cache), None when it
        was not seen or is not a 32FC1 image of ``shape``."""
        image = self._images[name].pop(stamp_ns, None)
        if image is None or image.encoding != "32FC1" or (image.height, image.width) != tuple(shape):
            return None
        try:
            return image.to_array()  # (H, W) float32 view of the received frame
        except ValueError:
            return None
