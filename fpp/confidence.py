"""Per-pixel confidence of a fringe order, in ``[0, 1]``, from every unwrapping method; the threshold that drops.

Classical methods (MF, MW, NT, heterodyne; :mod:`dptpu.fpp.tpu`): the confidence is ``Unwrapped.reliability``, the
**rounding margin** of the consistency residual of Eqs. (3)-(9): the method rounds a real quantity ``q`` to the
order (MF and MW: ``q`` of Eq. (5) / (7); heterodyne: each level of the beat tree, the smallest margin kept), and
``1 - 2 |q - Round(q)|`` is how far the residual ``q - k`` stays from the margin ``1/2`` at which noise would round
to the next order (1: no residual; 0: on the margin). NT: the key's distance to its decision boundary over the
table's tolerance (the same margin for the lookup of Eq. (9)). Gray code: twice the phase's distance, in periods,
to the nearest code edge (:func:`dptpu.fpp.graycode.unwrap_graycode`), a margin against a blurred edge, not a
rounding margin: ``dptpu unwrap`` keeps a threshold of 0 for it by default.

The DP-TPU network (:func:`network_confidence`): the largest of three supports for the published order ``k``,

- the network's own: ``1 - 2 |c - k|`` with ``c`` its continuous (unrounded) order, the rounding margin of the
  network's output on the scale of the classical one (0 where the neighbour consensus overruled the network by half
  an order or more);
- its prior's: 1 where ``k`` equals the coarse order it was given (:func:`dptpu.models.refine.network_prior`),
  0.5 one order off (a noisy prior of a 3-step capture often is), 0 further off.

- its neighbours' (given the wrapped phase): ``2 s - 1`` clipped to [0, 1], ``s`` the
  :func:`dptpu.fpp.order_support.neighbour_support` of the order: the share of the 9 x 9 window whose absolute
  phase agrees with the pixel's, each neighbour counted with its own (network and prior) confidence; above 0 only
  where more than half of the window confidently agrees. Where the prior is too noisy to support anything (MW at
  3 steps and 2 sigma: its coarse order is 2 or more orders off on many pixels the consensus puts right) this is
  what tells a right order inside a confident surface from one made up at an edge or in a patch.

An order that none of these supports is one the consensus vote made up from its neighbours: on the outside rigs of
``docs/nodes.md`` ("Confidence") every wrong order of a pure (not mixed) pixel was of that kind.

The network's result of a two-frequency capture is also held to the agreement of its two phases
(:func:`dptpu.fpp.frequency_consistency.frequency_consistency`, a phase confidence, not an order one): the
published confidence is the smaller of the two (:func:`dptpu.models.refine.refine_order_and_confidence`).

:func:`confident` applies a threshold (``min_confidence`` of the unwrap and cloud nodes, ``--min-confidence`` of
``dptpu unwrap`` / ``dptpu triangulate``) and counts what it drops. Defaults: :data:`DEFAULT_MIN_CONFIDENCE`.
"""
from __future__ import annotations

import numpy as np

from .order_support import neighbour_support

__all__ = ["DEFAULT_MIN_CONFIDENCE", "SUPPORT_RADIUS", "confident", "network_confidence"]

#: Default threshold of the confidence: a pixel below is dropped. Chosen on outside rigs (docs/nodes.md,
#: "Confidence"): it removes the orders the consensus made up (network confidence 0) and the classical orders whose
#: residual came within 0.4 of an order of the rounding margin.
DEFAULT_MIN_CONFIDENCE = 0.2
#: Half-width of the neighbour-support window of :func:`network_confidence`, pixels (9 x 9). Measured on the
#: outside rigs of ``dptpu eval cloud`` (DP-TPU MW, 3-step, 2 sigma; docs/nodes.md "Confidence"): radius 2, 3, 4, 5
#: published 94.65, 94.94, 95.16, 95.30 % of the surface at 0.051-0.052 % wrong.
SUPPORT_RADIUS = 4


def network_confidence(continuous: np.ndarray, order: np.ndarray, prior_order: np.ndarray,
                       valid: np.ndarray, wrapped_high: np.ndarray | None = None) -> np.ndarray:
    """Confidence ``(H, W)`` float32 of the network's published ``order`` (see the module docstring).

    Parameters
    ----------
    continuous : ndarray (H, W)
        The network's unrounded fringe order.
    order : ndarray (H, W) int
        The published order (the network's, rounded, after the neighbour consensus).
    prior_order : ndarray (H, W) int
        The coarse order the network received (its prior).
    valid : ndarray (H, W) bool
        Pixels with an order; 0 elsewhere.
    wrapped_high : ndarray (H, W), optional
        The wrapped phase of the order's frequency, radians: adds the neighbours' support (module docstring).
    """
    valid = np.asarray(valid, dtype=bool)
    continuous, order, prior_order = np.asarray(continuous), np.asarray(order), np.asarray(prior_order)
    if _float32_exact(continuous, order, prior_order):
        own, prior = _own_and_prior_float32(continuous, order, prior_order)
    else:
        k = order.astype(np.float64)
        own = np.clip(1.0 - 2.0 * np.abs(continuous.astype(np.float64) - k), 0.0, 1.0)
        prior = np.clip(1.0 - 0.5 * np.abs(k - prior_order.astype(np.float64)), 0.0, 1.0)
    confidence = np.maximum(own, prior)  # a new array: filled in place below
    np.copyto(confidence, 0.0, where=~(valid & np.isfinite(confidence)))
    if wrapped_high is not None:
        # only where the support can raise the confidence (a pixel at 1 keeps 1)
        support = neighbour_support(order, wrapped_high, valid, confidence, radius=SUPPORT_RADIUS,
                                    where=confidence < 1.0)
        support *= np.float32(2.0)  # 2 s - 1 clipped to [0, 1], float32 as the support
        support -= np.float32(1.0)
        np.clip(support, np.float32(0.0), np.float32(1.0), out=support)
        np.maximum(confidence, support, out=confidence)
    return confidence.astype(np.float32, copy=False)


def _float32_exact(continuous: np.ndarray, order: np.ndarray, prior_order: np.ndarray) -> bool:
    """Whether :func:`_own_and_prior_float32` gives the float64 formulas' float32 results bit for bit: a float32
    network output and integer orders below ``2^23`` in magnitude (they and their differences exact in float32)."""
    if continuous.dtype != np.float32 or not (np.issubdtype(order.dtype, np.integer)
                                              and np.issubdtype(prior_order.dtype, np.integer)):
        return False
    return order.size == 0 or all(-2 ** 23 < int(k.min()) and int(k.max()) < 2 ** 23 for k in (order, prior_order))


def _own_and_prior_float32(continuous: np.ndarray, order: np.ndarray,
                           prior_order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network's margin ``1 - 2 |c - k|`` and the prior's ``1 - |k - k_prior| / 2``, clipped to [0, 1], float32.

    Exact against float64 then float32: where ``|c - k| < 1/2`` the difference of the two float32 numbers is exact
    (Sterbenz's lemma for ``|k| >= 1``, ``c`` itself for ``k = 0``), so ``1 - 2 |c - k|`` is rounded once in either
    precision (float64 holds it exactly unless it lies within ``2^-30`` of 1, where both round to 1); elsewhere both
    clip to 0. The prior's term takes only 1, 1/2 and 0, from the orders' whole distance (exact in float32).
    """
    order_float = order.astype(np.float32)
    own = np.abs(continuous - order_float)
    own *= np.float32(-2.0)
    own += np.float32(1.0)
    np.clip(own, np.float32(0.0), np.float32(1.0), out=own)
    prior = np.abs(order_float - prior_order.astype(np.float32))
    prior *= np.float32(-0.5)
    prior += np.float32(1.0)
    np.clip(prior, np.float32(0.0), np.float32(1.0), out=prior)
    return own, prior


def confident(confidence: np.ndarray, valid: np.ndarray, min_confidence: float) -> tuple[np.ndarray, int]:
    """``(valid & (confidence >= min_confidence), how many valid pixels that dropped)``.

    ``min_confidence`` 0 keeps every valid pixel; it must lie in ``[0, 1]``.
    """
    if not (np.isfinite(min_confidence) and 0.0 <= min_confidence <= 1.0):
        raise ValueError(f"min_confidence must be in [0, 1]; got {min_confidence}")
    valid = np.asarray(valid, dtype=bool)
    if min_confidence <= 0.0:
        return valid.copy(), 0
    with np.errstate(invalid="ignore"):
        kept = valid & (np.asarray(confidence) >= min_confidence)
    return kept, int(np.count_nonzero(valid)) - int(np.count_nonzero(kept))
