"""What the named blurs do to the phase the geometric candidates fit: the twin's prediction, taken off.

A blur of the fringe images (``pixel_footprint``: a pixel's area and its lens; ``camera_defocus``: a blur after
the sampling; ``phase_filter``: a smoothing of the phase) moves each pixel's phase by a curvature term
``~ sigma^2 / 2 * laplacian(x)`` (the twin's :mod:`dptpu.sim.effects.footprint` and :mod:`dptpu.sim.effects.phase`
docstrings), and near a silhouette by much more: the sphere's limb, where the coordinate turns fastest, lies just
outside the 2 px edge band the geometric fits leave out. A registration and a ``calibration_error`` or
``lens_distortion`` fitted there absorb that pattern (on an 80 px sphere, a 0.8 px blur made a turn of ~1 deg and a
principal point ~14 px off that nearly cancel, each "significant").

So, once a blur is named, the twin at the best geometric model renders the reference with the named blurs and
without, decodes both like the data, and the difference (the blurs' phase bias, compared modulo a fringe period)
is taken off the measured coordinate before the geometric candidates are fitted again: what a calibration error
or a lens distortion must then explain is what the blurs do not.
"""
from __future__ import annotations

import numpy as np

from .footprint_fit import twin_sequences
from .rerender import decode, render_twin

__all__ = ["BLUR_EFFECTS", "blur_bias"]

#: Effects whose phase bias :func:`blur_bias` predicts (each a blur of the image or of the phase).
BLUR_EFFECTS = ("pixel_footprint", "camera_defocus", "phase_filter")


def blur_bias(measured, geometry, reference, material, effects) -> np.ndarray:
    """The projector-coordinate bias (H, W; projector px, 0 where either render does not decode) of the blur
    ``effects`` (twin effect dicts) on the twin of ``geometry`` (a registration: its rig and pose).

    Frames are rendered with the data's sequences (a phase file: the paper's ``f x 12`` and ``1 x 12``), noise
    free: the bias is the blurs' deterministic part.
    """
    names = [next(iter(e)) for e in effects]
    unknown = [n for n in names if n not in BLUR_EFFECTS]
    if unknown:
        raise ValueError(f"blur_bias: {', '.join(unknown)} not a blur; expected one of {', '.join(BLUR_EFFECTS)}")
    sequences, kwargs = twin_sequences(measured)
    bit_depth = kwargs.get("bit_depth", 8)
    to_x = measured.extent / (2.0 * np.pi * measured.frequency)
    period = measured.extent / measured.frequency

    def coordinate(with_effects) -> np.ndarray:
        frames = render_twin(geometry.rig, reference, geometry.pose, material, sequences, effects=with_effects,
                             **kwargs)
        return decode(frames, sequences, bit_depth=bit_depth, effects=with_effects) * to_x

    bias = coordinate(list(effects)) - coordinate([])
    bias = np.mod(bias + 0.5 * period, period) - 0.5 * period
    return np.where(np.isfinite(bias), bias, 0.0)
