"""Kernels of the least-squares phase (Eq. (2) of the paper): one matrix product, one arctangent.

``(3, N) weights @ (N, H*W) frames`` gives ``B sin(psi)``, ``B cos(psi)`` and ``A`` in one pass over the frames
(:func:`phase_sums`), in cache-sized blocks of pixels converted to float on the fly, so an 8/16-bit stack is never
copied whole. :func:`angle_0_2pi_float32` is an arctangent accurate to float32 (OpenCV's vectorized ``phase``,
about 1.7e-4 rad, corrected by one rotation) that costs a tenth of numpy's ``arctan2``.
"""
from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

_TWO_PI = 2.0 * np.pi
_TWO_PI_F32 = np.float32(_TWO_PI)  # 6.2831855, just above 2*pi; every float32 below it is below 2*pi
#: OpenBLAS splits a product of m*n*k above 65536 * 4 over threads; the blocks stay under it, so the product
#: runs on the calling thread (threads that spin for the other processes' cores only slow a loaded machine).
_BLOCK_MNK = 65536 * 4


@lru_cache(maxsize=64)
def _weights(steps: int, shift_sign: int, phase_offset: float, dtype: str) -> np.ndarray:
    """(3, N) rows ``-(2/N) sin(delta_n)``, ``(2/N) cos(delta_n)``, ``1/N`` (read-only), Eq. (2) scaled so the
    products are ``B sin(psi)``, ``B cos(psi)`` and ``A`` themselves."""
    delta = phase_offset + shift_sign * _TWO_PI * np.arange(steps) / steps  # (N,) radians
    weights = np.stack([-(2.0 / steps) * np.sin(delta), (2.0 / steps) * np.cos(delta),
                        np.full(steps, 1.0 / steps)]).astype(dtype)
    weights.flags.writeable = False
    return weights


def phase_sums(images: np.ndarray, *, shift_sign: int, phase_offset: float, dtype) -> np.ndarray:
    """``B sin(psi)``, ``B cos(psi)``, ``A`` of an (N, H, W) stack as one (3, H, W) array of ``dtype``.

    Computed in ``dtype`` (float32 or float64), in blocks of pixels small enough for the L2 cache and below
    OpenBLAS's threading threshold.
    """
    steps, height, width = images.shape
    dtype = np.dtype(dtype)
    weights = _weights(steps, int(shift_sign), float(phase_offset), dtype.str)  # (3, N)
    frames = images.reshape(steps, height * width)  # (N, H*W); a view when the stack is contiguous
    pixels = height * width
    out = np.empty((3, pixels), dtype=dtype)
    block = max(256, _BLOCK_MNK // (3 * steps) // 256 * 256)
    if frames.dtype == dtype:
        for start in range(0, pixels, block):
            np.matmul(weights, frames[:, start:start + block], out=out[:, start:start + block])
    else:
        work = np.empty((steps, min(block, pixels)), dtype=dtype)
        for start in range(0, pixels, block):
            chunk = work[:, :min(block, pixels - start)]
            np.copyto(chunk, frames[:, start:start + block], casting="unsafe")  # exact for <= 16-bit integers
            np.matmul(weights, chunk, out=out[:, start:start + block])
    return out.reshape(3, height, width)


def angle_0_2pi_float32(sine: np.ndarray, cosine: np.ndarray, magnitude: np.ndarray) -> np.ndarray:
    """``atan2(sine, cosine)`` in ``[0, 2*pi)``, float32 (H, W), from float32 (H, W) inputs; 0 where both are 0.

    ``magnitude`` is ``hypot(sine, cosine)``. OpenCV's ``phase`` gives ``theta0`` within about 1.7e-4 rad;
    rotating ``(cosine, sine)`` back by ``theta0`` leaves the small angle ``d = asin((sine cos(theta0) -
    cosine sin(theta0)) / magnitude)``, taken as its argument (the cube term is below 1e-11 rad), and
    ``theta0 + d`` is exact to float32 (max error vs float64 about 5e-7 rad with OpenCV's sine and cosine).
    """
    theta = cv2.phase(cosine, sine)  # (H, W) float32 in [0, 2*pi], ~1e-4 rad
    # magnitude None = an empty Mat, which OpenCV documents as all ones; its stub omits None
    cos0, sin0 = cv2.polarToCart(None, theta)  # type: ignore[call-overload]
    residual = np.multiply(sine, cos0)
    residual -= np.multiply(cosine, sin0, out=sin0)
    np.divide(residual, magnitude, out=residual, where=magnitude > 0)  # residual is 0 where magnitude is
    theta += residual
    np.add(theta, _TWO_PI_F32, out=theta, where=theta < 0)
    np.subtract(theta, _TWO_PI_F32, out=theta, where=theta >= _TWO_PI_F32)
    return theta


def angle_0_2pi_float64(sine: np.ndarray, cosine: np.ndarray) -> np.ndarray:
    """``atan2(sine, cosine)`` in ``[0, 2*pi)``, float64, numpy's (exact to float64; about 70 ns a pixel)."""
    angle = np.mod(np.arctan2(sine, cosine), _TWO_PI)
    angle[angle >= _TWO_PI] = 0.0  # mod of a tiny negative angle rounds up to exactly 2*pi
    return angle
