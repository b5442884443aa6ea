"""The projector's lens distortion seen along each camera ray: one polynomial per pixel, inverted by Newton.

Every point of a camera pixel's ray projects into the projector (undistorted, normalized) onto one line, the
pixel's epipolar line ``l = O x d`` (``O`` the camera centre and ``d`` the ray direction in the projector
frame, homogeneous). Parameterize that line by the ideal (undistorted) projector pixel coordinate ``c`` along
the fringe axis, ``c = k . [x, y, 1]`` with ``k`` the axis' row of the projector ``K``: then ``x`` and ``y``
are affine in ``c`` and the measured (distorted) coordinate

    m(c) = k . [distort(x(c), y(c)), 1]

is a polynomial in ``c`` (Brown-Conrady, ``distortion.py``): degree 7 with ``k3``, else 5 with ``k2``, else 3.
Its coefficients are found once per rig by interpolation at Chebyshev nodes of ``u = (c - mid) / half``
(exact for a polynomial), so a scan costs a few Horner passes over (H, W) arrays: Newton's method
``u <- u - (m(u) - m_measured) / m'(u)`` converges quadratically to the fixed point that the textbook
iteration (triangulate, project, re-distort, correct) approaches linearly. It starts from a quintic fit of the
inverse; passes that only need to get close run in float32 (twice the SIMD lanes of float64 in this numpy
build), the last ones in float64 until the predicted error is below :data:`PREDICTED_ERROR_PX`.
"""
from __future__ import annotations

import numpy as np

from .calibration import DeviceModel
from .distortion import distort

#: Newton stops once the largest correction of a pass is below this, projector pixels.
STEP_TOLERANCE_PX = 1e-7
#: ... or once the error left after a pass, bounded by ``kappa * step**2`` (quadratic convergence, ``kappa`` the
#: largest ``|m''| / (2 |m'|)`` of the rig, times :data:`_KAPPA_SAFETY`), is below this, projector pixels.
PREDICTED_ERROR_PX = 1e-8
_KAPPA_SAFETY = 4.0
_KAPPA_SAMPLES = np.linspace(-1.25, 1.25, 21)  # u where kappa is sampled: the projector and a margin
_GUESS_DEGREE = 5
_GUESS_SAMPLES = np.linspace(-1.0, 1.0, 21)  # measured u (the projector) where the guess error is measured
#: Error of a float32 Newton pass's result from its rounding alone (m ~ 1000 px, a few float32 roundings).
_FLOAT32_FLOOR_PX = 2e-4


def _chebyshev_nodes(count: int) -> np.ndarray:
    return np.cos(np.pi * (np.arange(count) + 0.5) / count)  # (count,) in (-1, 1)


def _monomial_fit(nodes: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Coefficients (n+1, ...) in increasing powers of the polynomial through ``values`` (n+1, ...) at ``nodes``."""
    vandermonde = np.vander(nodes, len(nodes), increasing=True)  # (n+1, n+1)
    flat = values.reshape(len(nodes), -1)
    return (np.linalg.inv(vandermonde) @ flat).reshape(values.shape)


def horner(coefficients: np.ndarray, u: np.ndarray | np.floating) -> np.ndarray:
    """``sum_k coefficients[k] * u**k`` for coefficients (n+1, ...) and ``u`` (...), in place on one buffer."""
    value = np.multiply(coefficients[-1], u)
    for coefficient in coefficients[-2:0:-1]:
        value += coefficient
        value *= u
    value += coefficients[0]
    return value


class RayDistortion:
    """Measured projector coordinate as a polynomial of the ideal one, per camera pixel, and its inverse.

    Parameters
    ----------
    projector : DeviceModel
        The projector (``K``, ``dist``, ``R``, ``T``, ``size``); world to projector ``X_p = R X + T``.
    camera_center : ndarray (3,)
        Camera centre in world coordinates.
    rays : ndarray (H, W, 3)
        Ray directions of the camera pixels in world coordinates (undistorted).
    axis : {0, 1}
        Projector pixel axis that the phase measures (0: column ``u``, 1: row ``v``).

    Convention: ``u = (c - mid) / half`` with ``mid = half = extent / 2``, so ``u`` runs over ``[-1, 1]`` across
    the projector's extent ``size[axis]`` (pixel coordinates, 0-based centres); the polynomial holds for every
    ``c`` (it is exact), the interval only scales it.
    """

    def __init__(self, projector: DeviceModel, camera_center: np.ndarray, rays: np.ndarray, axis: int):
        k1, k2, p1, p2, k3 = np.asarray(projector.dist, dtype=np.float64)
        self.degree = 7 if k3 != 0 else 5 if k2 != 0 else 3
        extent = float(projector.size[axis])
        self.mid_px = self.half_px = extent / 2.0
        center = projector.R @ np.asarray(camera_center, dtype=np.float64) + projector.T  # (3,) projector frame
        directions = rays @ projector.R.T  # (H, W, 3) projector frame
        line = np.cross(center, directions)  # (H, W, 3): epipolar line l . [x, y, 1] = 0
        row = projector.K[axis]  # c = row . [x, y, 1] (ideal pixel coordinate)
        with np.errstate(divide="ignore", invalid="ignore"):
            det = line[..., 0] * row[1] - line[..., 1] * row[0]  # (H, W); 0: line along iso-c (degenerate)
            # [x, y] = offset + slope * c solves l0 x + l1 y = -l2, row0 x + row1 y = c - row2.
            self._x = ((line[..., 1] * row[2] - line[..., 2] * row[1]) / det, -line[..., 1] / det)
            self._y = ((line[..., 2] * row[0] - line[..., 0] * row[2]) / det, line[..., 0] / det)
        self._projector = projector
        self._axis = axis
        nodes = _chebyshev_nodes(self.degree + 1)
        measured = np.stack([self.measured(self.mid_px + self.half_px * node) for node in nodes])  # (n+1, H, W)
        self.coefficients = _monomial_fit(nodes, measured)  # (n+1, H, W): m(u) in pixels
        derivative = self.coefficients[1:] * np.arange(1, self.degree + 1)[:, None, None]  # (n, H, W) m'(u)
        # m' only scales Newton's step: float32 (relative error ~1e-7) costs nothing in accuracy.
        self.derivative = derivative.astype(np.float32)
        self.kappa = self._kappa()
        # Initial guess: a quintic in the measured u through exact inverses at Chebyshev nodes.
        guess_nodes = _chebyshev_nodes(_GUESS_DEGREE + 1)
        ideal = np.stack([self._solve(np.full(line.shape[:2], self.mid_px + self.half_px * node), node, 40)
                          for node in guess_nodes])  # (6, H, W) ideal u
        self.guess = _monomial_fit(guess_nodes, ideal)  # (6, H, W)
        self.guess_error_px = self._guess_error()
        # float32 copies for the passes that only need to get close; one float32 pass unless the guess is
        # already within the reach of one float64 pass.
        self.guess = self.guess.astype(np.float32)  # (6, H, W): only ever evaluated in float32
        self._coefficients32 = self.coefficients.astype(np.float32)
        reach = _KAPPA_SAFETY * self.kappa / self.half_px * (2.0 * self.guess_error_px + _FLOAT32_FLOOR_PX) ** 2
        self.float32_passes = 0 if reach <= PREDICTED_ERROR_PX else 1

    def _subgrid(self, array: np.ndarray) -> np.ndarray:
        """Every 4th pixel of every 4th row, and the last row and column, of (k, H, W) ``array``: (k, h, w)."""
        height, width = array.shape[1:]
        rows = np.unique(np.append(np.arange(0, height, 4), height - 1))
        cols = np.unique(np.append(np.arange(0, width, 4), width - 1))
        return array[:, rows][:, :, cols]

    def _guess_error(self) -> float:
        """Largest ``|guess - exact inverse|`` in pixels over :data:`_GUESS_SAMPLES` on the pixel subgrid."""
        coefficients, derivative = self._subgrid(self.coefficients), self._subgrid(self.derivative).astype(float)
        guess = self._subgrid(self.guess)
        largest = 0.0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for measured_u in _GUESS_SAMPLES:
                start = horner(guess, np.float64(measured_u))  # (h, w) ideal u
                u = start.copy()
                target = self.mid_px + self.half_px * measured_u
                for _ in range(6):  # from within about a pixel: converged to rounding after 4
                    u -= (horner(coefficients, u) - target) / horner(derivative, u)
                largest = max(largest, float(np.fmax.reduce(np.abs(u - start), axis=None)) * self.half_px)
        return largest if np.isfinite(largest) else np.inf

    def _kappa(self) -> float:
        """Largest ``|m''(u)| / (2 |m'(u)|)`` over :data:`_KAPPA_SAMPLES` and the pixel subgrid (it varies slowly
        across the image; u units, >= 0); inf where ``m'`` vanishes (a fold: the convergence prediction is then
        not used)."""
        first = self._subgrid(self.derivative).astype(np.float64)  # (n, h, w)
        second = first[1:] * np.arange(1, self.degree)[:, None, None]  # (n-1, h, w)
        kappa = 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            for u in _KAPPA_SAMPLES:
                ratio = np.abs(horner(second, np.float64(u))) / (2.0 * np.abs(horner(first, np.float64(u))))
                kappa = max(kappa, float(np.fmax.reduce(ratio, axis=None)))
        return kappa if np.isfinite(kappa) else np.inf

    def measured(self, ideal_px: np.ndarray) -> np.ndarray:
        """Measured (distorted) projector coordinate of the ideal coordinate ``ideal_px`` (..., H, W) along each
        pixel's epipolar line, by the distortion model itself (``distortion.distort``)."""
        x = self._x[0] + self._x[1] * ideal_px
        y = self._y[0] + self._y[1] * ideal_px
        xy_d = distort(np.stack([x, y], axis=-1), self._projector.dist)
        row = self._projector.K[self._axis]
        return row[0] * xy_d[..., 0] + row[1] * xy_d[..., 1] + row[2]

    def ideal_u(self, measured_px: np.ndarray, *, max_iterations: int = 6,
                pixels: np.ndarray | None = None) -> np.ndarray:
        """Ideal (undistorted) coordinate as ``u = (c - mid) / half`` (H, W) of the measured one (H, W), pixels.

        The quintic guess and :attr:`float32_passes` Newton passes in float32, then float64 Newton passes until
        the largest correction is below :data:`STEP_TOLERANCE_PX`, the predicted error below
        :data:`PREDICTED_ERROR_PX`, or after ``max_iterations`` passes. NaN stays NaN.

        ``pixels`` (M,) flat pixel indices: ``measured_px`` (M,) holds those pixels' coordinates only, and so does
        the result. Each pixel goes through the same operations as in a whole image, so it gets the same value
        bit for bit whenever the passes stop after as many passes (the largest correction is taken over the pixels
        given: never more passes than the whole image needs, fewer only where the whole image held a pixel slower
        to converge, whose extra pass moves the others by less than :data:`STEP_TOLERANCE_PX`).
        """
        measured_px = np.asarray(measured_px, dtype=np.float64)
        guess, coefficients, coefficients32, derivative = self._at(pixels)
        measured32 = measured_px.astype(np.float32)
        u32 = measured32 - np.float32(self.mid_px)
        u32 *= np.float32(1.0 / self.half_px)
        u32 = horner(guess, u32)  # (H, W) ideal u, float32
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for _ in range(self.float32_passes):
                step = horner(coefficients32, u32)
                step -= measured32
                step /= horner(derivative, u32)
                u32 -= step
        return self._solve(measured_px, u32.astype(np.float64), max_iterations, u32, coefficients, derivative)

    def _at(self, pixels: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The float32 guess, the float64 and float32 coefficients and the derivative, (k, H, W) each, or (k, M) at
        the flat pixel indices ``pixels`` (M,): the guess and the float64 coefficients gathered, the float32 ones
        and the derivative made from those as :meth:`__init__` makes them (the same values; half the scattered
        reads, which cost more than the arithmetic)."""
        if pixels is None:
            return self.guess, self.coefficients, self._coefficients32, self.derivative
        index = np.asarray(pixels, dtype=np.intp)
        guess = np.take(self.guess.reshape(len(self.guess), -1), index, axis=1)
        coefficients = np.take(self.coefficients.reshape(len(self.coefficients), -1), index, axis=1)
        derivative = (coefficients[1:] * np.arange(1, self.degree + 1)[:, None]).astype(np.float32)
        return guess, coefficients, coefficients.astype(np.float32), derivative

    def ideal(self, measured_px: np.ndarray, *, max_iterations: int = 6) -> np.ndarray:
        """Ideal (undistorted) projector coordinate (H, W), pixels, of the measured one (H, W); see :meth:`ideal_u`."""
        u = self.ideal_u(measured_px, max_iterations=max_iterations)
        u *= self.half_px
        u += self.mid_px
        return u

    def _solve(self, measured_px, u, max_iterations: int, u32=None, coefficients=None,
               derivative=None) -> np.ndarray:
        """Newton passes on ``m(u) = measured_px`` (H, W) from ``u`` (scalar or (H, W), overwritten); returns ``u``.

        ``m(u)`` is evaluated in float64, ``m'`` in float32 at ``u32`` (``u`` in float32, given or cast): its
        relative error, about 1e-7, only adds ``1e-7 * step`` to a pass's error. ``coefficients`` and
        ``derivative``: those of the pixels ``measured_px`` holds (default: every pixel's, (k, H, W)).
        """
        coefficients = self.coefficients if coefficients is None else coefficients
        derivative = self.derivative if derivative is None else derivative
        if np.shape(u) != np.shape(measured_px):
            u = np.array(np.broadcast_to(u, np.shape(measured_px)), dtype=np.float64)
        if u32 is None:
            u32 = u.astype(np.float32)
        step_tolerance = STEP_TOLERANCE_PX / self.half_px  # u units
        kappa_px = _KAPPA_SAFETY * self.kappa * self.half_px  # predicted error (px) per squared step (u units)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for _ in range(max_iterations):
                step = horner(coefficients, u)  # m(u), pixels
                step -= measured_px
                step /= horner(derivative, u32)  # / m'(u) (pixels per unit u): Newton's step, u units
                u -= step
                largest = np.fmax.reduce(np.abs(step, out=step), axis=None)  # ignores NaN pixels
                if not largest > step_tolerance or kappa_px * largest**2 <= PREDICTED_ERROR_PX:
                    break  # converged (or every pixel NaN)
                u32 = u.astype(np.float32)
        return u
