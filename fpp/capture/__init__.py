"""Capture folders, format ``dptpu-capture/1``: read, validate, load frames, write.

A capture folder holds the camera frames of one scan and a ``capture.yaml`` that says what they are
(docs/capture-format.md is the full specification)::

    format: dptpu-capture/1
    camera: {size: [640, 480], bit_depth: 8}     # width, height; 8 or 16 (PNG, mono)
    projector: {size: [912, 1140]}                # width, height
    fringe_axis: x                                # phase varies along projector x (vertical stripes)
    phase_shift_sign: -1                          # image n is A + B cos(phi + sign*2*pi*n/N)
    sequences:
      - {frequency: 96, steps: 12, images: [f96_s00.png, ...]}
      - {kind: graycode, bits: 5, period: 60, images: [g0.png, ...]}

Public API (each from the module that does it: :mod:`.model`, :mod:`.reading`, :mod:`.loading`,
:mod:`.writing`; :mod:`.document_checks` is the checker that names the file and the key):

- :func:`read_capture` -- parse and validate a folder into a :class:`Capture` (no pixels are read);
- :func:`load_sequence_images`, :func:`load_image`, :func:`load_reference`, :func:`load_ground_truth`
  -- read frames, checking size and bit depth against ``camera``;
- :func:`write_capture` -- write arrays as a capture folder (PNG frames + ``capture.yaml``);
- :func:`write_capture_yaml` -- write the ``capture.yaml`` of a :class:`Capture` whose frames exist.

Validation is strict: a missing required key, a wrong type, an impossible value or an image count that
does not match ``steps`` raises ``ValueError`` naming the file and the key; listed files that do not
exist raise ``FileNotFoundError`` naming every one of them. Extra (unknown) keys are allowed at the top
level and in sequences; they are kept in ``extras``.

Convention: ``camera.size`` and ``projector.size`` are ``(width, height)`` in pixels, while image
arrays are ``(H, W)`` and stacks ``(N, H, W)``. ``phi = 2*pi*f*x_p/W_p`` with ``W_p`` the projector
extent along ``fringe_axis`` (width for ``x``, height for ``y``); a ``period`` ``T`` in projector
pixels is the frequency ``f = W_p / T``.
"""

from .loading import load_ground_truth, load_image, load_images, load_reference, load_sequence_images
from .model import (
    CAPTURE_FILE,
    CAPTURE_FORMAT,
    Capture,
    GraycodeFrames,
    GraycodeSequence,
    GroundTruth,
    PatternLevels,
    PhaseFrames,
    PhaseSequence,
)
from .reading import read_capture
from .writing import write_capture, write_capture_yaml

__all__ = [
    "CAPTURE_FORMAT",
    "CAPTURE_FILE",
    "PatternLevels",
    "PhaseSequence",
    "GraycodeSequence",
    "Capture",
    "GroundTruth",
    "PhaseFrames",
    "GraycodeFrames",
    "read_capture",
    "load_image",
    "load_images",
    "load_sequence_images",
    "load_reference",
    "load_ground_truth",
    "write_capture",
    "write_capture_yaml",
]
