"""Real 3-step network inputs from the CFPE captures, with the 12-step three-period heterodyne as the reference.

Data: ``../shared/data/cfpe`` (its README): scene ``CC``, frame ``CCIIh.png`` with ``II = 12 i + s`` for projector
periods ``T_i = 42, 45, 48`` px (``i = 0, 1, 2``) over a 1920 px projector and step ``s = 0..11``; the projected
step is ``+2 pi s / 12`` (``phase_shift_sign: +1``, verified in tests/fpp/test_cfpe_real.py).

What is real, what is derived (nothing is synthesized here):

- **3-step inputs**: steps 0, 4 and 8 of each 12-step sequence are a real 3-step sequence (shifts 0, 2pi/3,
  4pi/3, Eq. (1) with the opposite sign): their wrapped phases ``psi3_i`` (Eq. (2)) carry the real camera
  noise and the real projector nonlinearity as a 3-step phase sees it.
- **high frequency**: ``f_h = 1920 / 42 = 45.71`` periods, ``psi_h = psi3_0``.
- **low frequency** (:func:`low_phase`), rescaled to the phase ``2 pi x_p / W`` of ``f_l = 1``: the pair maps onto
  **MF with f_l = 1** (Eq. (5)), the convention the network was trained with, at ``f_h / f_l = 45.7`` (inside the
  training frequencies 32-80). Two constructions from the real 3-step phases:
  ``het12`` (default): the beat ``psi3_0 - psi3_1`` of ``f_12 = 1920/630 = 3.05`` unwrapped by the beat of beats
  ``psi3_0 - 2 psi3_1 + psi3_2`` of ``f_123 = 1920/5040 = 0.381`` (absolute, ``f_123 < 1``): the second level of
  the heterodyne tree, so the classical MF order of the pair IS the classical 3-step heterodyne order;
  ``beat123``: the beat of beats itself. Neither has the noise of a 3-step f = 1 pattern (the training data's):
  the beats add the phases' errors (``sqrt(2)``, ``sqrt(6)`` times one phase's) and the rescaling multiplies them
  by ``1 / f_12`` or ``1 / f_123``; that is out of the training distribution, and measured (:func:`input_rms`).
- **the cascade** (:func:`cfpe_cascade`, :mod:`.beat_cascade`): the same heterodyne as two MF pairs, one per level
  (the beat 42/45 against the beat of beats; the 42 px phase against the absolute beat), for a solver at each
  level; its level 2 with the classical level-1 order is the ``het12`` pair.
- **reference**: the 12-step phases of the three periods unwrapped by the heterodyne beat tree
  (``unwrap_heterodyne``): ``Phi_ref``; reference order ``Round((Phi_ref - psi_h) / 2 pi)``.
- **valid**: every 3-step and 12-step sequence has modulation >= 2 % of full scale and no saturated frame, and the
  12-step heterodyne unwrapped the pixel onto the projector.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from dptpu.fpp import tpu
from dptpu.fpp.capture import CAPTURE_FILE, read_capture
from dptpu.fpp.phase import quality_mask, wrapped_phase
from dptpu.fpp.phase_harmonics import (
    HarmonicPhaseError,
    ProjectorPhaseResponse,
    fit_harmonic_phase_error,
    remove_harmonic_phase_error,
)
from dptpu.fpp.phase_response_calibration import calibrate_phase_response

from .beat_cascade import CascadePair, beat_frequencies, cascade_pair
from .measured_pair import MeasuredPair, mf_coarse_order, reference_order

__all__ = ["PERIODS_PX", "PROJECTOR_WIDTH_PX", "FREQUENCIES", "INPUT_STEPS", "LOW_PHASES", "load_cfpe_frames",
           "beat_frequencies", "low_phase", "build_pair", "cfpe_pair", "cfpe_cascade", "cfpe_phase_error",
           "cfpe_phase_response", "input_rms", "write_cfpe_capture"]

#: Projector periods of the three sequences, in file order (highest frequency first).
PERIODS_PX = (42, 45, 48)
PROJECTOR_WIDTH_PX = 1920
#: Steps of each 12-step sequence that form the 3-step input (shifts 0, 2pi/3, 4pi/3).
INPUT_STEPS = (0, 4, 8)
#: The projected step is ``+2 pi s / N`` (README; tests/fpp/test_cfpe_real.py).
SHIFT_SIGN = 1
MIN_MODULATION_FRACTION = 0.02
_FULL_SCALE = 255.0
_TWO_PI = 2.0 * np.pi
#: Periods across the projector width of the three sequences, highest first.
FREQUENCIES = tuple(PROJECTOR_WIDTH_PX / p for p in PERIODS_PX)


def load_cfpe_frames(cfpe_dir, scene: str) -> np.ndarray:
    """The 36 fringe frames of a CFPE scene, ``(3, 12, H, W)`` uint8: period index, step, image.

    Raises
    ------
    FileNotFoundError
        A frame ``CCIIh.png`` is missing (the message names it).
    ValueError
        ``scene`` is not two digits, or a frame is not an 8-bit mono image of the first frame's size.
    """
    folder = Path(cfpe_dir)
    if not (isinstance(scene, str) and len(scene) == 2 and scene.isdigit()):
        raise ValueError(f"CFPE scene must be two digits such as '06'; got {scene!r}")
    frames: list[np.ndarray] = []
    for index in range(12 * len(PERIODS_PX)):
        path = folder / f"{scene}{index:02d}h.png"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such CFPE frame (expected {folder}/{scene}00h.png .. "
                                    f"{scene}35h.png)")
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None or image.ndim != 2 or image.dtype != np.uint8:
            raise ValueError(f"{path}: expected an 8-bit mono PNG")
        if frames and image.shape != frames[0].shape:
            raise ValueError(f"{path}: size {image.shape} differs from the scene's first frame {frames[0].shape}")
        frames.append(image)
    height, width = frames[0].shape
    return np.stack(frames).reshape(len(PERIODS_PX), 12, height, width)


def _phases(frames: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Wrapped phases of each sequence (N, H, W) and their joint quality mask (H, W)."""
    phases, mask = [], None
    for images in frames:
        maps = wrapped_phase(images, shift_sign=SHIFT_SIGN)
        ok = quality_mask(images, maps.modulation, min_modulation=MIN_MODULATION_FRACTION * _FULL_SCALE)
        phases.append(maps.phase)
        mask = ok if mask is None else mask & ok
    if mask is None:
        raise ValueError("no phase sequence in the frames")
    return phases, mask


LOW_PHASES = ("het12", "beat123")


def low_phase(psi, frequencies, kind: str = "het12") -> np.ndarray:
    """The low phase of the MF pair, ``f_l = 1``, from the wrapped phases of three frequencies.

    Parameters
    ----------
    psi : sequence of 3 ndarray (H, W)
        Wrapped phases (radians, ``[0, 2 pi)``) of ``f_0 > f_1 > f_2``.
    frequencies : 3 floats
        Periods across the projector width (CFPE: ``1920/42, 1920/45, 1920/48``).
    kind : {"het12", "beat123"}
        ``beat123``: the beat of beats ``psi_0 - 2 psi_1 + psi_2`` (frequency ``f_123 <= 1``, absolute), rescaled
        by ``1 / f_123``. ``het12``: the beat ``psi_0 - psi_1`` of ``f_12`` unwrapped by the beat of beats (the
        second level of the heterodyne tree, Eq. (5) with ``f_12 / f_123``), rescaled by ``1 / f_12``; with it
        the MF order of ``f_0`` equals the classical three-frequency heterodyne order.

    Returns
    -------
    ndarray (H, W)
        ``2 pi x_p / W`` plus the errors of the construction, wrapped to ``[0, 2 pi)``.
    """
    if kind not in LOW_PHASES:
        raise ValueError(f"low phase must be one of {', '.join(LOW_PHASES)}; got {kind!r}")
    f_12, f_123 = beat_frequencies(frequencies)
    beat_12 = np.mod(psi[0] - psi[1], _TWO_PI)  # phase of f_12
    beat = np.mod(beat_12 - np.mod(psi[1] - psi[2], _TWO_PI), _TWO_PI)  # phase of f_123, [0, 2pi)
    # f_123 spans [0, 2 pi f_123) over the projector; values in the gap above are noise below 0
    beat = np.where(beat > np.pi * (1.0 + f_123), beat - _TWO_PI, beat)
    if kind == "beat123":
        return np.mod(beat / f_123, _TWO_PI)
    order = np.rint((beat * f_12 / f_123 - beat_12) / _TWO_PI)  # Eq. (5)
    return np.mod((beat_12 + _TWO_PI * order) / f_12, _TWO_PI)


def build_pair(name: str, psi3, mask3, reference_phase, frequencies, *, extent_px: int, low: str = "het12",
               provenance: dict | None = None) -> MeasuredPair:
    """An MF pair from 3-step phases of three frequencies and a reference absolute phase of the highest.

    Shared by the measured data (:func:`cfpe_pair`) and the twin's training samples
    (:mod:`dptpu.experiments.downstream`), so both are built the same way.

    Parameters
    ----------
    psi3 : sequence of 3 ndarray (H, W)
        Input wrapped phases, radians, highest frequency first.
    mask3 : ndarray (H, W) bool
        Pixels whose inputs pass the quality mask.
    reference_phase : ndarray (H, W)
        Reference absolute phase of ``frequencies[0]`` (NaN where unknown).
    frequencies : 3 floats
        Periods across the projector width.
    """
    f_h = float(frequencies[0])
    reference_phase = np.asarray(reference_phase, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        on_projector = (reference_phase >= 0) & (reference_phase < _TWO_PI * f_h)
    valid = np.asarray(mask3, bool) & on_projector
    psi_h = np.where(valid, psi3[0], 0.0)
    psi_l = np.where(valid, low_phase(psi3, frequencies, low), 0.0)
    phi_ref = np.where(valid, reference_phase, np.nan)
    return MeasuredPair(name=name, wrapped_high=psi_h, wrapped_low=psi_l,
                        coarse_order=mf_coarse_order(psi_h, psi_l, f_h, valid),
                        reference_order=reference_order(phi_ref, psi_h), reference_phase=phi_ref, valid=valid,
                        frequency_high=f_h, frequency_low=1.0, method="mf", extent_px=int(extent_px),
                        provenance=dict(provenance or {}))


def cfpe_pair(cfpe_dir, scene: str, *, low: str = "het12",
              phase_error: HarmonicPhaseError | ProjectorPhaseResponse | None = None) -> MeasuredPair:
    """The MF pair of a CFPE scene from its real 3-step frames, scored against its 12-step heterodyne.

    Parameters
    ----------
    cfpe_dir : path
        The CFPE data folder (``../shared/data/cfpe``).
    scene : str
        ``"01"``, ``"04"``, ``"06"`` or ``"08"``.
    low : {"het12", "beat123"}
        Construction of the low phase (:func:`low_phase`).
    phase_error : HarmonicPhaseError or ProjectorPhaseResponse, optional
        The projector's harmonic phase error of 3-step phases (:func:`cfpe_phase_error`), removed from each 3-step
        phase first (:func:`dptpu.fpp.phase_harmonics.remove_harmonic_phase_error`); or the rig calibration of
        ``dptpu calibrate response`` (:func:`cfpe_phase_response`), applied as every phase computation of a rig
        applies it (:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`); default: the phases as
        captured.

    Returns
    -------
    MeasuredPair
        ``f_h = 1920/42``, ``f_l = 1``, method ``mf``; see the module docstring.
    """
    psi3, mask, phi_ref = _inputs_and_reference(cfpe_dir, scene, phase_error)
    low_text = ("the three-period beat psi(42) - 2 psi(45) + psi(48) (f = 1920/5040 = 0.381)" if low == "beat123"
                else "the beat psi(42) - psi(45) (f = 1920/630 = 3.05) unwrapped by the three-period beat "
                     "(f = 0.381): the second level of the heterodyne tree")
    return build_pair(f"cfpe{scene}", psi3, mask, phi_ref, FREQUENCIES, extent_px=PROJECTOR_WIDTH_PX,
                      low=low, provenance={
                          "data": f"CFPE scene {scene} (real frames, ../shared/data/cfpe)",
                          "wrapped_high": "real: 3-step phase (steps 0, 4, 8 of 12) of period 42 px, f_h = 1920/42",
                          "wrapped_low": f"real: {low_text}, from the 3-step phases, rescaled to f_l = 1",
                          "method": "mf (Eq. 5), f_h / f_l = 45.7" + (
                              "; the MF order equals the classical 3-step three-frequency heterodyne order"
                              if low == "het12" else ""),
                          "reference": "real: 12-step phases of the three periods, heterodyne unwrapping",
                      })


def _inputs_and_reference(cfpe_dir, scene: str, phase_error) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """``(psi3, mask, phi_ref)``: the 3-step phases of the three periods (response removed when ``phase_error`` is
    given, :func:`cfpe_pair`), the joint quality mask of the 3-step and 12-step sequences and the 12-step
    heterodyne's absolute phase of period 42 px (NaN where it failed)."""
    frames = load_cfpe_frames(cfpe_dir, scene)  # (3, 12, H, W)
    psi3, mask3 = _phases(frames[:, list(INPUT_STEPS)])
    if isinstance(phase_error, ProjectorPhaseResponse):
        psi3 = [phase_error.correct(psi, len(INPUT_STEPS)) for psi in psi3]
    elif phase_error is not None:
        psi3 = [remove_harmonic_phase_error(psi, phase_error) for psi in psi3]
    psi12, mask12 = _phases(frames)
    reference = tpu.unwrap_heterodyne(psi12, FREQUENCIES, valid=mask12)
    return psi3, mask3 & mask12, np.where(reference.valid, reference.absolute_phase, np.nan)


def cfpe_cascade(cfpe_dir, scene: str, *,
                 phase_error: HarmonicPhaseError | ProjectorPhaseResponse | None = None) -> CascadePair:
    """The heterodyne of a CFPE scene's real 3-step frames as the cascade's two MF pairs
    (:mod:`.beat_cascade`): level 1 the beat 42/45 (``f = 3.05``) against the three-period beat (``f = 0.381``),
    level 2 the 42 px phase against level 1's absolute beat; the same pixels and reference as :func:`cfpe_pair`
    (whose ``het12`` pair is the level-2 pair with the classical level-1 order). ``phase_error`` as there."""
    psi3, mask, phi_ref = _inputs_and_reference(cfpe_dir, scene, phase_error)
    return cascade_pair(f"cfpe{scene}", psi3, mask, phi_ref, FREQUENCIES, extent_px=PROJECTOR_WIDTH_PX, provenance={
        "data": f"CFPE scene {scene} (real frames, ../shared/data/cfpe)",
        "level 1": "real: the beat psi(42) - psi(45) (f = 3.05) against the three-period beat psi(42) - 2 psi(45) "
                   "+ psi(48) (f = 0.381), from the 3-step phases (steps 0, 4, 8 of 12): MF with f_h / f_l = 8",
        "level 2": "real: the 3-step phase of period 42 px (f_h = 45.71) against level 1's absolute beat rescaled "
                   "to f_l = 1: MF with f_h / f_l = 45.7",
        "reference": "real: 12-step phases of the three periods, heterodyne unwrapping",
    })


def input_rms(cfpe_dir, scene: str, *, low: str = "het12") -> dict:
    """RMS differences (radians) of the 3-step inputs from the 12-step phases on a scene's valid pixels.

    Returns ``{"high_rad": ..., "low_rad": ..., "low_in_high_periods": ..., "pixels": ...}``: ``high`` is
    ``psi3(42) - psi12(42)`` wrapped to ``(-pi, pi]``; ``low`` is the rescaled three-period beat against the
    12-step heterodyne phase scaled to ``f = 1``; ``low_in_high_periods`` is the low error times ``f_h / 2 pi``, the
    error it brings into the MF order (an order is lost where it exceeds 0.5).
    """
    pair = cfpe_pair(cfpe_dir, scene, low=low)
    frames = load_cfpe_frames(cfpe_dir, scene)
    psi12 = wrapped_phase(frames[0], shift_sign=SHIFT_SIGN).phase
    valid = pair.valid
    high = np.angle(np.exp(1j * (pair.wrapped_high - psi12)))[valid]
    low_true = np.mod(pair.reference_phase / pair.frequency_high, _TWO_PI)
    low_error = np.angle(np.exp(1j * (pair.wrapped_low - low_true)))[valid]
    rms_low = float(np.sqrt(np.mean(low_error ** 2)))
    return {"high_rad": float(np.sqrt(np.mean(high ** 2))), "low_rad": rms_low,
            "low_in_high_periods": rms_low * pair.frequency_high / _TWO_PI, "pixels": int(valid.sum())}


def cfpe_phase_error(cfpe_dir, scenes) -> HarmonicPhaseError:
    """The CFPE projector's harmonic phase error of 3-step phases (steps 0, 4, 8), fitted against the 12-step phases
    of the same frames over ``scenes`` and all three periods (:func:`dptpu.fpp.phase_harmonics.
    fit_harmonic_phase_error`): a calibration of the projector's response, to be applied to other scenes."""
    measured, reference, valid = [], [], []
    for scene in scenes:
        frames = load_cfpe_frames(cfpe_dir, scene)  # (3, 12, H, W)
        psi3, mask3 = _phases(frames[:, list(INPUT_STEPS)])
        psi12, mask12 = _phases(frames)
        measured += psi3
        reference += psi12
        valid += [mask3 & mask12] * len(psi3)
    return fit_harmonic_phase_error(measured, reference, valid, steps=len(INPUT_STEPS))


def write_cfpe_capture(cfpe_dir, scene: str, folder) -> Path:
    """A ``dptpu-capture/1`` folder for a CFPE scene: a ``capture.yaml`` in ``folder`` (created) naming the real
    frames by absolute path (nothing copied): periods 42, 45, 48 px, 12 steps each, ``phase_shift_sign: +1``,
    ``CC36h.png`` as the white reference (docs/capture-format.md "The real CFPE captures as a capture folder")."""
    cfpe_dir, folder = Path(cfpe_dir).resolve(), Path(folder)
    load_cfpe_frames(cfpe_dir, scene)  # every frame there and readable, or the error names it
    folder.mkdir(parents=True, exist_ok=True)
    document = {
        "format": "dptpu-capture/1", "camera": {"size": [640, 480], "bit_depth": 8},
        "projector": {"size": [PROJECTOR_WIDTH_PX, 1080]}, "fringe_axis": "x", "phase_shift_sign": SHIFT_SIGN,
        "pattern": {"offset": 128 / 255, "amplitude": 96 / 255},
        "sequences": [{"period": period, "steps": 12,
                       "images": [str(cfpe_dir / f"{scene}{12 * i + step:02d}h.png") for step in range(12)]}
                      for i, period in enumerate(PERIODS_PX)],
        "references": {"white": str(cfpe_dir / f"{scene}36h.png")},
        "source": "yongleex/CFPE data/recordings/2 (MIT)",
    }
    (folder / CAPTURE_FILE).write_text(yaml.safe_dump(document, sort_keys=False))
    return folder


def cfpe_phase_response(cfpe_dir, scenes) -> ProjectorPhaseResponse:
    """The CFPE projector's response as ``dptpu calibrate response`` calibrates it from the capture folders of
    ``scenes`` (:func:`write_cfpe_capture`; :func:`dptpu.fpp.phase_response_calibration.calibrate_phase_response`):
    3-step phases (steps 0, 4, 8) against the 12-step ones, every period pooled, terms at 3, 6 and 9 times the
    phase. What a user with these captures writes into the rig file."""
    with tempfile.TemporaryDirectory(prefix="dptpu-cfpe-") as scratch:
        captures = [read_capture(write_cfpe_capture(cfpe_dir, scene, Path(scratch) / scene)) for scene in scenes]
        return calibrate_phase_response(captures, steps=[len(INPUT_STEPS)]).response
