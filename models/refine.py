"""DP-TPU refinement of a classical capture result (:func:`dptpu.fpp.reconstruct.unwrap_capture`), no torch.

``dptpu unwrap --model PATH`` and the library call :func:`refine_capture_result`: the two-frequency result
of MF, MW or NT gives the network its inputs (the wrapped phases of the high and the low sequence and the
classical fringe order); the network's rounded order, post-processed by the neighbour consensus of
:mod:`dptpu.models.consensus` (full resolution, no ground truth), replaces the classical one on every
pixel that passes the capture's quality mask (so NT pixels whose lookup key was rejected get an order too), and the
absolute phase and validity are recomputed as ``unwrap_capture`` does: ``psi + 2*pi*k`` (Eq. (3)), valid
where the quality mask holds and the phase lies on the projector, ``0 <= phi < 2*pi*f``. ``reliability``
becomes the network's confidence (:func:`dptpu.fpp.confidence.network_confidence`: its distance to an integer order,
its agreement with its prior and its neighbours' support), held to the two frequencies' agreement per pixel
(:func:`dptpu.fpp.frequency_consistency.frequency_consistency`) and per patch (0 on the patches whose order the low
frequency rejects, :func:`dptpu.fpp.region_consistency.rejected_regions`).

The default model (:func:`choose_model`, ``dptpu unwrap`` and ``dptpu triangulate`` without ``--model``): the
shipped one, for the methods it serves and fringes of at most :data:`DEFAULT_MAX_PERIODS_PER_PIXEL` periods per
camera pixel, measured on the wrapped phase (:func:`fringe_density`), never on an unwrapped one (whose wrong orders
are the steps the network is there to fix).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import NamedTuple

import numpy as np

from dptpu.fpp.bracketed_median import bracketed_median
from dptpu.fpp.confidence import network_confidence
from dptpu.fpp.frequency_consistency import frequency_consistency, quantization_residual_noise
from dptpu.fpp.low_period_disputes import low_period_disputes
from dptpu.fpp.methods import TWO_FREQUENCY_METHODS
from dptpu.fpp.nt_twins import twin_ambiguous
from dptpu.fpp.region_consistency import rejected_regions

from .consensus import consensus_order
from .inference import FringeOrderModel, shipped_model_path
from .nt_prior import mf_representation
from .projector_ends import coarse_order_at_ends

__all__ = ["DEFAULT_MAX_PERIODS_PER_PIXEL", "REFINABLE_METHODS", "Refinement", "choose_model", "fringe_density",
           "network_prior", "refine_capture_result", "refine_order", "refine_order_and_confidence", "refinement",
           "resolve_model"]

#: Classical methods whose result the network refines (the paper's three two-frequency methods).
REFINABLE_METHODS = TWO_FREQUENCY_METHODS
#: The shipped model is applied by default only to fringes of at most this many periods per camera pixel
#: (a period of 4 pixels or more). Its training fringes had periods of about 6 to 15 pixels; near the
#: Nyquist limit (0.5 periods per pixel) the 3x3 neighbourhoods it relies on no longer see a smooth phase,
#: and on such captures it was measured to change right orders (see docs/network.md).
DEFAULT_MAX_PERIODS_PER_PIXEL = 0.25


def resolve_model(value, method: str) -> FringeOrderModel | None:
    """The model named by ``--model``: a path, ``"none"``, or None for the shipped default.

    Returns None (classical result) for ``"none"``, or by default when there is no shipped model, or
    ``method`` is not one of :data:`REFINABLE_METHODS`, or the shipped model was not trained on ``method``
    (its metadata lists the methods of its training set). An explicit path with a method outside
    :data:`REFINABLE_METHODS` is a ValueError; a missing or corrupt file is a
    :class:`~dptpu.models.inference.ModelLoadError`.
    """
    if value is not None and str(value).lower() == "none":
        return None
    if value is None:
        path = shipped_model_path()
        if path is None or method not in REFINABLE_METHODS:
            return None
        model = FringeOrderModel.load(path)
        return model if model.serves(method) else None
    if method not in REFINABLE_METHODS:
        raise ValueError(f"--model refines the orders of {', '.join(REFINABLE_METHODS)}; method {method!r} "
                         "is not one of them (pass --model none)")
    return FringeOrderModel.load(Path(value))


def refine_capture_result(result, model: FringeOrderModel, *, consensus: bool = True):
    """A copy of a two-frequency ``CaptureResult`` with the network's fringe order.

    Parameters
    ----------
    result : dptpu.fpp.reconstruct.CaptureResult
        From ``unwrap_capture(..., method="mf" | "mw" | "nt")``; carries ``wrapped_phases`` (high, low)
        and ``quality``.
    model : FringeOrderModel
    consensus : bool
        Post-process the rounded order with :func:`dptpu.models.consensus.consensus_order` (default; it costs
        more than the network, docs/benchmarks.md "Model: the consensus vote"); False gives the network's
        rounded order alone.

    Returns
    -------
    CaptureResult
        ``fringe_order`` (H, W) int32 refined, ``absolute_phase`` (H, W) float64, NaN where invalid,
        ``valid`` recomputed, ``reliability`` the network's confidence (0 where invalid); ``method`` unchanged
        (the caller records the model).
    """
    if result.method not in REFINABLE_METHODS or len(result.wrapped_phases) != 2 or result.quality is None:
        raise ValueError(f"the network refines a two-frequency {'/'.join(REFINABLE_METHODS)} result with its "
                         f"wrapped phases; got method {result.method!r}")
    psi_h, psi_l = result.wrapped_phases
    quality = np.asarray(result.quality, dtype=bool)
    f_h, f_l = result.frequencies[0], result.frequencies[1]
    floor = (quantization_residual_noise(result.quantization_noise[0], result.quantization_noise[1], f_h, f_l)
             if len(result.quantization_noise) >= 2 else None)
    order, confidence = refine_order_and_confidence(model, result.method, psi_h, psi_l, result.fringe_order, f_h, f_l,
                                                    quality, classical_valid=result.valid, consensus=consensus,
                                                    consistency_floor=floor, modulation=result.modulation)
    absolute = psi_h + 2.0 * np.pi * order  # Eq. (3), (H, W)
    with np.errstate(invalid="ignore"):
        valid = quality & (absolute >= 0.0) & (absolute < 2.0 * np.pi * result.frequency)
    return dataclasses.replace(
        result, fringe_order=np.where(valid, order, 0).astype(np.int32),
        absolute_phase=np.where(valid, absolute, np.nan), valid=valid,
        reliability=np.where(valid, confidence, 0.0).astype(np.float64))


def refine_order(model: FringeOrderModel, method: str, psi_h, psi_l, classical_order, f_h: float, f_l: float,
                 valid, *, classical_valid=None, consensus: bool = True) -> np.ndarray:
    """DP-TPU's fringe order of ``f_h`` for one two-frequency result, ``(H, W)`` int32.

    MF and MW: the network on the wrapped phases and the classical order (the paper's Fig. 8b), that order read
    at the projector's ends (:func:`dptpu.models.projector_ends.coarse_order_at_ends`: Eq. (5) / (7) where a
    noisy phase near 0 or 2pi stays at its end of the projector). NT: the network on NT's prior in the MF
    representation (:func:`dptpu.models.nt_prior.mf_representation`: the low order by band consensus, the low
    absolute phase at one period, its MF order). Then the consensus of :mod:`dptpu.models.consensus`, with
    that prior's order as the classical one.

    Parameters
    ----------
    model : FringeOrderModel
        Serving ``method`` (:meth:`FringeOrderModel.serves`).
    method : {"mf", "mw", "nt"}
    psi_h, psi_l : ndarray (H, W)
        Wrapped phases of ``f_h`` and ``f_l``, radians (NaN allowed where not ``valid``).
    classical_order : ndarray (H, W) int
        The classical method's order of ``f_h`` (Eq. (5), (7) or (9)).
    f_h, f_l : float
        Periods across the projector.
    valid : ndarray (H, W) bool
        Pixels to decide; the others keep ``classical_order``.
    classical_valid : ndarray (H, W) bool, optional
        Where ``classical_order`` is the method's answer (NT rejects some keys); elsewhere the vote uses the
        network's order as the classical one. Default: ``valid``.
    consensus : bool
        Post-process with :func:`dptpu.models.consensus.consensus_order` (default).
    """
    return refine_order_and_confidence(model, method, psi_h, psi_l, classical_order, f_h, f_l, valid,
                                       classical_valid=classical_valid, consensus=consensus)[0]


class Refinement(NamedTuple):
    """DP-TPU's result of one two-frequency scan (:func:`refinement`)."""

    order: np.ndarray  #: (H, W) int32, the fringe order of ``f_h``
    confidence: np.ndarray  #: (H, W) float32 in [0, 1], 0 where not valid
    absolute_phase: np.ndarray  #: (H, W) float64, ``psi_h + 2 pi order`` (Eq. (3)) on every pixel, valid or not


def refine_order_and_confidence(model: FringeOrderModel, method: str, psi_h, psi_l, classical_order, f_h: float,
                                f_l: float, valid, *, classical_valid=None, consensus: bool = True,
                                consistency_floor: np.ndarray | None = None,
                                modulation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_order`'s order and its confidence, ``(order (H, W) int32, confidence (H, W) float32)``: the first
    two fields of :func:`refinement`."""
    refined = refinement(model, method, psi_h, psi_l, classical_order, f_h, f_l, valid,
                         classical_valid=classical_valid, consensus=consensus, consistency_floor=consistency_floor,
                         modulation=modulation)
    return refined.order, refined.confidence


def refinement(model: FringeOrderModel, method: str, psi_h, psi_l, classical_order, f_h: float, f_l: float, valid, *,
               classical_valid=None, consensus: bool = True, consistency_floor: np.ndarray | None = None,
               modulation: np.ndarray | None = None) -> Refinement:
    """:func:`refine_order`'s order, its confidence and the absolute phase they were judged on (the unwrap node
    publishes it, computed once).

    The confidence is the smaller of :func:`dptpu.fpp.confidence.network_confidence` (the network's continuous
    output, its prior and its neighbours' support of the published order) and
    :func:`dptpu.fpp.frequency_consistency.frequency_consistency` (the low frequency's phase against the published
    absolute phase), 0 where not ``valid``. NT: 0 also on the solid patches where the order and ``classical_order``
    (the per-pixel lookup) differ by one low period (:func:`dptpu.fpp.low_period_disputes.low_period_disputes`: a
    band the prior gave the other low order), and where neither the pixel nor its region tells the order from a
    near-twin that the scan's noise can reach (:func:`dptpu.fpp.nt_twins.twin_ambiguous`; ``modulation`` (H, W),
    optional, scales each pixel's noise there). Parameters as :func:`refine_order`'s; ``consistency_floor`` (H, W),
    optional: the agreement's per-pixel noise floor from the images' rounding
    (:func:`dptpu.fpp.frequency_consistency.quantization_residual_noise`; :func:`refine_capture_result` passes it).
    """
    if method not in REFINABLE_METHODS or not model.serves(method):
        raise ValueError(f"the model {model.path} (trained for {', '.join(model.trained_methods)}) does not refine "
                         f"method {method!r}")
    valid = np.asarray(valid, dtype=bool)
    if model.kind == "dptpu":
        wrapped_low, classical = network_prior(method, psi_h, psi_l, classical_order, f_h, f_l, valid,
                                               classical_valid=classical_valid)
        continuous, mask = _continuous_order(model, psi_h, wrapped_low, classical, f_h, valid)
        order = np.where(mask, np.rint(continuous), classical).astype(np.int32)
    else:  # the U-Net baseline: the wrapped phases alone (it takes no order)
        continuous, mask = _continuous_order(model, psi_h, psi_l, classical_order, f_h, valid)
        order = np.where(mask, np.rint(continuous), np.asarray(classical_order)).astype(np.int32)
        classical_valid = valid if classical_valid is None else np.asarray(classical_valid, dtype=bool) & valid
        classical = np.where(classical_valid, classical_order, order)  # the network's where classical has none
    if consensus:
        order = consensus_order(order, classical, np.where(valid, psi_h, 0.0), valid)
    confidence = network_confidence(continuous, order, classical, mask, wrapped_high=np.where(mask, psi_h, 0.0))
    absolute = np.asarray(psi_h, dtype=np.float64) + 2.0 * np.pi * order  # Eq. (3)
    consistency = frequency_consistency(absolute, psi_l, f_h, f_l, mask, floor=consistency_floor)
    np.minimum(confidence, consistency, out=confidence)  # both float32 (H, W), the confidence a new array
    np.copyto(confidence, np.float32(0.0), where=rejected_regions(absolute, psi_l, f_h, f_l, mask))
    if method == "nt":  # a band whose prior took the other low order than the per-pixel lookup, solidly: no confidence
        both = valid if classical_valid is None else valid & np.asarray(classical_valid, dtype=bool)
        disputed = low_period_disputes(order, np.asarray(classical_order), f_h / f_l, both)
        # nor an order that neither its pixel nor its region tells from a near-twin noise can reach (fpp.nt_twins)
        disputed |= twin_ambiguous(absolute, psi_l, f_h, f_l, mask, modulation=modulation)
        np.copyto(confidence, np.float32(0.0), where=disputed)
    return Refinement(order, confidence, absolute)


def _continuous_order(model: FringeOrderModel, psi_h, wrapped_low, coarse, f_h: float,
                      valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network's unrounded order (H, W) float32 on the pixels it decides (``valid`` with finite inputs), and
    that mask; as :meth:`FringeOrderModel.refine` masks its inputs."""
    arrays = [np.asarray(a) for a in (psi_h, wrapped_low, coarse)]
    mask = np.array(valid, dtype=bool)
    for a in arrays:
        if not np.issubdtype(a.dtype, np.integer):
            mask &= np.isfinite(a)
    high, low, order = (_masked_float32(a, mask) for a in arrays)
    return model.predict(high, low, order, float(f_h)), mask


def _masked_float32(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``np.where(mask, values, 0).astype(np.float32)`` in one pass: the same cast where ``mask``, 0 elsewhere."""
    out = np.zeros(mask.shape, np.float32)
    np.copyto(out, values, where=mask, casting="unsafe")
    return out


def network_prior(method: str, psi_h, psi_l, classical_order, f_h: float, f_l: float, valid, *,
                  classical_valid=None) -> tuple[np.ndarray, np.ndarray]:
    """The physics prior DP-TPU receives for ``method``: ``(wrapped_low, coarse_order)``, each ``(H, W)``.

    MF and MW: ``psi_l`` and the order of Eq. (5) / (7) read at the projector's ends
    (:func:`dptpu.models.projector_ends.coarse_order_at_ends`). NT: the MF representation of its band prior
    (:func:`dptpu.models.nt_prior.mf_representation`). Parameters as :func:`refine_order`'s; ``coarse_order``
    is int32, 0 where not ``valid``.
    """
    valid = np.asarray(valid, dtype=bool)
    if method == "nt":
        classical_valid = valid if classical_valid is None else np.asarray(classical_valid, dtype=bool) & valid
        nt = mf_representation(psi_h, psi_l, np.where(classical_valid, classical_order, np.nan), f_h, f_l, valid)
        return nt.wrapped_low, nt.coarse_order
    if method in ("mf", "mw"):
        return np.asarray(psi_l), coarse_order_at_ends(method, psi_h, psi_l, f_h, f_l, valid,
                                                       classical_order=classical_order)
    raise ValueError(f"network_prior takes method mf, mw or nt; got {method!r}")


def fringe_density(wrapped_high, valid=None) -> float:
    """Median fringe periods per camera pixel of a wrapped phase, along its faster image direction.

    The median over neighbour pairs (both valid) of ``|wrap(d psi)| / 2pi``, ``wrap`` into ``(-pi, pi]``, along
    image rows and along columns; the larger of the two. It depends on the wrapped phase alone, not on an
    unwrapping (whose wrong orders would add steps of whole periods). A density above the Nyquist limit of 0.5
    folds back below it (such fringes are not resolved by the camera at all). 0.0 when fewer than 2 valid
    neighbours exist.

    Parameters
    ----------
    wrapped_high : ndarray (H, W)
        Wrapped phase of the high frequency, radians; NaN allowed.
    valid : ndarray (H, W) bool, optional
        Pixels to use; default the finite ones.
    """
    psi = np.asarray(wrapped_high, dtype=np.float64)
    if valid is not None:
        psi = np.where(np.asarray(valid, dtype=bool), psi, np.nan)
    medians = []
    for axis in (0, 1):
        steps = np.diff(psi, axis=axis)
        steps = steps[np.isfinite(steps)]  # |wrap(d psi)| / 2 pi, in place: the same float64 operations in turn
        steps += np.pi
        np.fmod(steps, 2.0 * np.pi, out=steps)  # np.mod's value: fmod with the period added to a negative remainder
        np.add(steps, 2.0 * np.pi, out=steps, where=steps < 0)
        steps -= np.pi
        np.abs(steps, out=steps)
        steps /= 2.0 * np.pi
        medians.append(float(bracketed_median(steps)) if steps.size else 0.0)
    return max(medians)


def choose_model(model: FringeOrderModel | None, value, method: str, wrapped_high,
                 valid=None) -> tuple[FringeOrderModel | None, str]:
    """The model ``dptpu unwrap`` / ``dptpu triangulate`` apply, and why none when none: ``(model, note)``.

    ``model`` is :func:`resolve_model` of ``value`` (``--model``; resolved before the capture is read, so a bad
    model file fails fast) and ``method``. An explicit path is always applied; by default (None) the
    shipped model is applied when it serves ``method`` and the capture's fringes are at most
    :data:`DEFAULT_MAX_PERIODS_PER_PIXEL` periods per camera pixel (:func:`fringe_density` of the wrapped phase of
    the high frequency). ``note`` is "" when a model is applied or ``--model none`` was asked, else the reason.
    """
    if value is not None:
        return model, ""
    if model is None:
        if shipped_model_path() is None:
            return None, "no shipped model"
        return None, f"the shipped model does not serve method {method}"
    density = fringe_density(wrapped_high, valid)
    if density > DEFAULT_MAX_PERIODS_PER_PIXEL:
        return None, (f"shipped model skipped: fringes of {density:.2f} periods per camera pixel, more than the "
                      f"{DEFAULT_MAX_PERIODS_PER_PIXEL:g} it serves (pass --model to apply it anyway)")
    return model, ""
