"""Input checks shared by the fpp modules: one message for one mistake, wherever it is made."""
from __future__ import annotations

import math
import numbers
from typing import TypeGuard

import numpy as np


def is_finite_real(value: object) -> TypeGuard[float]:
    """True for a finite real number (Python or NumPy, not a bool); False for NaN, inf and anything else.

    A real number too large for a float (a huge ``int``) counts as not finite.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def check_image_stack(images, name: str = "images", *, min_frames: int = 3, max_frames: int | None = None,
                      what: str = "N") -> np.ndarray:
    """An (N, H, W) stack of integer or float frames with ``min_frames <= N (<= max_frames)``, all finite.

    ``what`` names the first axis in the message, e.g. "bits" for a Gray code stack.
    """
    images = np.asarray(images)
    count_ok = images.ndim == 3 and images.shape[0] >= min_frames
    if max_frames is not None:
        count_ok = count_ok and images.shape[0] <= max_frames
    if not count_ok:
        bound = f"{what} >= {min_frames}" if max_frames is None else f"{min_frames} <= {what} <= {max_frames}"
        raise ValueError(f"{name} must have shape ({what}, H, W) with {bound}; got {images.shape}")
    dtype = images.dtype
    if dtype == np.bool_ or not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)):
        raise ValueError(f"{name} must have an integer or float dtype; got {dtype}")
    if np.issubdtype(dtype, np.floating):
        if np.isnan(images).any():
            raise ValueError(f"{name} contain NaN")
        if np.isinf(images).any():
            raise ValueError(f"{name} contain inf")
    return images


def check_projector_size(projector_size) -> tuple[int, int]:
    """``(width, height)`` of a projector as two positive integers."""
    try:
        width, height = projector_size
    except (TypeError, ValueError):
        raise ValueError(f"projector_size must be (width, height); got {projector_size!r}") from None
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(f"projector_size {name} must be a positive integer; got {value!r} "
                             f"in projector_size={projector_size!r}")
    return int(width), int(height)
