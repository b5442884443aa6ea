"""MF and MW's coarse fringe order at the projector's two ends (the network's prior, no torch).

Eqs. (5) and (7) read the fringe order of ``f_h`` from a phase ``Phi`` that spans the projector once: MF's
low phase at ``f_l = 1``, MW's equivalent phase ``psi_eq = psi_h - psi_l`` (Eq. (6), ``f_eq = f_h - f_l = 1``
for the paper's pairs). ``Phi`` is wrapped into ``[0, 2pi)``, and its two ends are the projector's two ends: a
pixel near the projector's first column has ``Phi`` just above 0, and noise moves it to just below ``2pi``,
where Eq. (5) or (7) gives an order near ``f_h`` instead of near 0. At 2 sigma MW's ``psi_eq`` has
``sqrt(2)`` times the phase noise, and a scene that sees the projector's edge gets a whole region of such
orders; the network, which never saw the projector's edge in training, then shifted that region by one order
(unseen rig, 640x480, MW f_h = 80, 2 sigma: a 3,792-pixel region at orders 0-3, all off by one).

:func:`coarse_order_at_ends` reads ``Phi`` near an end (within :data:`END_BAND_RAD` of 0 or ``2pi``) relative to
its local mean ``m`` over a window of :data:`WINDOW_PX`: with the phases there written in ``(-pi, pi]``, ``m`` is
the window's plain mean, and ``Phi' = m + wrap(Phi - m)`` is the signed phase, plus ``2pi`` where ``m < 0`` (the
projector's last column). Then Eq. (5) / (7) unchanged. Away from the ends ``Phi' = Phi``; near the first column
a noisy ``Phi`` just below ``2pi`` becomes slightly negative (order ~0), near the last a ``Phi`` just above 0
becomes slightly above ``2pi`` (order ~``f_h - 1``). What is left: pixels within the noise of the projector's
edge, whose window's mean is within its noise of 0.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["END_BAND_RAD", "WINDOW_PX", "coarse_order_at_ends"]

#: Side of the square window of the local mean, pixels.
WINDOW_PX = 5
#: Pixels whose phase lies within this of 0 (or 2pi) are near an end: their window's values all lie near the
#: end too (the phase spans the projector once, 0.01 rad a projector column at 912 px), radians.
END_BAND_RAD = 0.5 * np.pi
_TWO_PI = 2.0 * np.pi


def coarse_order_at_ends(method: str, psi_h, psi_l, f_h: float, f_l: float, valid, *,
                         classical_order=None) -> np.ndarray:
    """Eq. (5) (``"mf"``) or Eq. (7) (``"mw"``) on the projector-spanning phase read at the projector's ends.

    Parameters
    ----------
    method : {"mf", "mw"}
    psi_h, psi_l : ndarray (H, W)
        Wrapped phases of ``f_h`` and ``f_l``, radians in ``[0, 2pi)`` (anything where not ``valid``).
    f_h, f_l : float
        Periods across the projector; MF needs ``f_l <= 1``, MW ``0 < f_h - f_l <= 1`` (so that the phase read
        spans the projector at most once).
    valid : ndarray (H, W) bool
    classical_order : ndarray (H, W) int, optional
        The method's order (Eq. (5) / (7)) when already computed: only the pixels near the ends are computed
        again (a 640x480 scan that does not see the projector's ends costs two comparisons a pixel).

    Returns
    -------
    ndarray (H, W) int32
        The order of ``f_h``; 0 where not ``valid``.
    """
    if method == "mf":
        if not 0 < f_l <= 1:
            raise ValueError(f"MF reads its order from a low frequency f_l <= 1; got f_l = {f_l!r}")
        spanning = f_l
    elif method == "mw":
        spanning = f_h - f_l
        if not 0 < spanning <= 1:
            raise ValueError(f"MW needs 0 < f_h - f_l <= 1 (Eq. (6)); got f_h = {f_h!r}, f_l = {f_l!r}")
    else:
        raise ValueError(f"coarse_order_at_ends takes method 'mf' or 'mw'; got {method!r}")
    valid = np.asarray(valid, dtype=bool)
    psi_h = np.asarray(psi_h, dtype=np.float32)
    psi_l = np.asarray(psi_l, dtype=np.float32)
    ratio = np.float32(f_h / spanning)
    with np.errstate(invalid="ignore"):  # NaN where not valid: masked below
        phi = psi_l if method == "mf" else np.mod(psi_h - psi_l, np.float32(_TWO_PI))  # [0, 2pi), Eq. (6)
        if classical_order is None:
            order = np.rint((ratio * phi - psi_h) * np.float32(1.0 / _TWO_PI)).astype(np.int32)  # Eq. (5) / (7)
        else:
            order = np.array(classical_order, dtype=np.int32)
        order[~valid] = 0
        near = (phi < END_BAND_RAD) | (phi > _TWO_PI - END_BAND_RAD)
        near &= valid
        if not near.any():
            return order
        rows, cols = np.nonzero(near.any(axis=1))[0], np.nonzero(near.any(axis=0))[0]
        pad = WINDOW_PX // 2
        box = (slice(max(rows[0] - pad, 0), rows[-1] + pad + 1), slice(max(cols[0] - pad, 0), cols[-1] + pad + 1))
        signed = phi[box].astype(np.float32)  # a copy: (-pi, pi], both ends near 0
        signed[signed > np.pi] -= np.float32(_TWO_PI)
        signed[~valid[box] | ~np.isfinite(signed)] = 0.0
        sums = cv2.boxFilter(signed, -1, (WINDOW_PX, WINDOW_PX), normalize=False)
        inside = near[box]
        # Phi' = m + wrap(Phi - m): the signed phase, + 2pi where the local mean m is below 2pi (the last column)
        phi_near = signed[inside] + np.float32(_TWO_PI) * (sums[inside] < 0)
        order[box][inside] = np.rint((ratio * phi_near - psi_h[box][inside]) * np.float32(1.0 / _TWO_PI))
    return order
