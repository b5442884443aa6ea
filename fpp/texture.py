"""The surface's texture (its grey level as the camera sees it under the projector's light) of one scan.

A robot colours a point cloud by the surface's own brightness, not by the fringe modulation: a dark glossy part
and a bright matte one may have the same modulation ``B`` and very different textures. Two sources, the first that
a scan has:

1. a **white** frame (the projector full on) in the sequence, minus the **black** frame (full off) when there is
   one: the projector's light alone, ambient light and the camera's dark level taken out
   (``texture = I_white - I_black``); the white frame alone when no black one was projected;
2. otherwise the **mean intensity** ``A`` of the phase-shifted frames (Eq. (2) of the paper, ``A = mean_n I_n``):
   the surface under the projector's mid-grey (the pattern's offset), ambient light and the dark level included.
   On a projector whose patterns are ``offset + amplitude cos(.)`` of full scale, ``A`` is about ``offset`` times
   the white frame's texture plus the ambient term, so it orders surfaces as the white frame does but is not the
   same number.

Both come in the camera's digital numbers (DN), float32, at the frames' full resolution.
"""
from __future__ import annotations

import numpy as np

__all__ = ["texture_image"]


def texture_image(*, background: np.ndarray | None = None, white: np.ndarray | None = None,
                  black: np.ndarray | None = None) -> np.ndarray:
    """The texture (H, W) float32 in DN: ``white - black``, ``white``, or the mean intensity ``background``.

    Parameters
    ----------
    background : ndarray (H, W), optional
        Mean intensity ``A`` of the phase-shifted frames (Eq. (2)); used only without ``white``.
    white, black : ndarray (H, W), optional
        The frames taken under the projector full on and full off (uint8/uint16 or float DN); ``black`` only with
        ``white``.

    Returns
    -------
    ndarray (H, W) float32
        ``white - black`` (may dip below 0 by the noise where the projector adds nothing), ``white``, or
        ``background``.
    """
    if white is not None:
        texture = np.asarray(white, dtype=np.float32).copy()
        if texture.ndim != 2:
            raise ValueError(f"white must be an (H, W) image; got shape {texture.shape}")
        if black is not None:
            black = np.asarray(black)
            if black.shape != texture.shape:
                raise ValueError(f"black must have the white frame's shape {texture.shape}; got {black.shape}")
            texture -= black.astype(np.float32, copy=False)
        return texture
    if black is not None:
        raise ValueError("a black frame needs a white frame: the texture is white - black")
    if background is None:
        raise ValueError("texture_image needs a white frame or the mean intensity (background) of the phase frames")
    background = np.asarray(background, dtype=np.float32)
    if background.ndim != 2:
        raise ValueError(f"background must be an (H, W) image; got shape {background.shape}")
    return background
