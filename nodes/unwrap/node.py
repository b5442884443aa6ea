"""Unwrap node: temporal phase unwrapping of each scan's wrapped phase maps into an absolute phase.

Classical methods from :mod:`dptpu.fpp.tpu` (the paper's Eqs. (3)-(9)); optionally the fringe order is then
refined by the DP-TPU network (``model``, run by :mod:`dptpu.models.inference` with onnxruntime).

Topics (defaults; remappable)

=========================== ============= ===== ===============================================
topic                       type          dir   notes
=========================== ============= ===== ===============================================
``/scanner/phase``          PhaseMaps     in    reliable, depth 10
``/camera/camera_info``     CameraInfo    in    transient local, its sole publisher: the camera size a PhaseMaps must
                                                have (a scan of another size is refused before it is unwrapped)
``/scanner/absolute_phase`` AbsolutePhase out   reliable, depth 10; the highest (or ``high_frequency``)
``/scanner/intensity``      Image         out   reliable, depth 10; 32FC1: the modulation B (DN) of the unwrapped
                                                frequency, the scan's stamp; published just before its AbsolutePhase
``/scanner/status``         ScanStatus    out   one per scan: ``processing`` (OK) or ``failed``
=========================== ============= ===== ===============================================

Parameters

=================== ========= ===================================================================================
name                default   meaning
=================== ========= ===================================================================================
``method``          "mf"      ``mf`` (Eq. (5) in float32, needs a frequency <= 1), ``mw`` (Eqs. (6)-(7), needs
                              ``0 < f_h - f_l <= 1``), ``nt`` (Eqs. (8)-(9)) or ``heterodyne`` (beat tree of all;
                              takes neither ``high_frequency`` nor ``low_frequency``)
``model``           "none"    a DP-TPU ``.onnx`` model refining the classical fringe order (mf/mw/nt, on the prior
                              of :func:`dptpu.models.refine.network_prior`), ``shipped`` (the packaged model),
                              ``auto`` (the packaged model where it serves the method and, per scan, the fringes:
                              the gate of ``dptpu unwrap``, :func:`dptpu.models.refine.choose_model`, measured on
                              the wrapped phase; a scan it skips says why in its status) or ``none``
``consensus``       false     with ``model``: post-process the network's order with the neighbour consensus of
                              :mod:`dptpu.models.consensus` (what ``dptpu unwrap --model`` and the accuracy
                              figures of docs/model-eval.md use; it adds to every scan's latency, see
                              docs/benchmarks.md, so off by default)
``high_frequency``  0.0       frequency to unwrap (periods across the projector); 0 = the highest of the scan
``low_frequency``   0.0       the auxiliary frequency of mf/mw/nt; 0 = chosen as ``dptpu unwrap`` does
``min_confidence``  0.2       pixels whose confidence (``AbsolutePhase.reliability``: the classical rounding margin,
                              or the network's confidence; :mod:`dptpu.fpp.confidence`) is lower are invalid;
                              counted (``pixels_low_confidence``, the scan's status reason); 0 keeps all
``max_pixels``      12582912  the most pixels (H x W) of a PhaseMaps unwrapped while no CameraInfo has given the
                              camera's size (4096 x 3072); a larger scan is refused, so that one forged or wrong
                              message cannot grow the node to many times its memory
=================== ========= ===================================================================================

Every parameter applies from the next scan (``dptpu param set /unwrap method nt``), checked as at start-up
(``method``, ``model`` and ``consensus`` together; a new model is loaded before it is accepted; once scans arrive,
a ``method`` must unwrap their frequencies): a bad value is refused with the reason and the old one stays.

Valid pixels: valid in the PhaseMaps, accepted by the method, at least ``min_confidence`` and on the
projector (``0 <= Psi < 2*pi*f``, as :func:`dptpu.fpp.reconstruct.unwrap_capture` requires). The network's
confidence is judged as ``dptpu unwrap`` judges it, with the two frequencies' agreement floored at what the frames'
rounding explains (:func:`dptpu.fpp.frequency_consistency.integer_frames_floor`) where the PhaseMaps carries its step
counts (``PhaseMaps.steps``; the phase node sends them). Run:
``python -m dptpu.nodes.unwrap --ros-args -p method:=nt``; design: ``docs/nodes.md``.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from dptpu.fpp import tpu
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE, confident
from dptpu.fpp.frequencies import select_frequencies
from dptpu.fpp.frequency_consistency import integer_frames_floor
from dptpu.fpp.methods import PHASE_SEQUENCE_METHODS
from dptpu.fpp.nt_twins import scan_twin_warning, twin_ambiguous
from dptpu.graph.known_publishers import SOLE_PUBLISHER
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, within
from dptpu.messages import AbsolutePhase, CameraInfo, Image, PhaseMaps, ScanStatus
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import LATCHED_QOS, STATUS_QOS, DecodeErrorCount, ScanFailures, fails_the_scan, scan_status

__all__ = ["UnwrapNode", "load_model", "main", "refined"]

_TWO_PI = 2.0 * np.pi
#: Default ``max_pixels``: a 4096 x 3072 (12.6 MP) camera, the largest a scan is unwrapped at without a CameraInfo.
DEFAULT_MAX_PIXELS = 4096 * 3072


class UnwrapNode(Node):
    """PhaseMaps -> AbsolutePhase (see the module docstring).

    Counters: ``scans_published``, ``scans_rejected``, ``pixels_nan`` (pixels marked valid whose phase was NaN),
    ``pixels_low_confidence`` (valid pixels dropped below ``min_confidence``), ``scans_without_model`` (``auto``
    scans the gate left classical).
    """

    def __init__(self, node_name: str = "unwrap", **node_options):
        super().__init__(node_name, **node_options)
        rules = self._rules = ParameterRules(self)
        # the last scan's frequencies (the projector's sequence is fixed while it runs): a method set at run time
        # must unwrap them
        self._scan_frequencies: tuple[float, ...] = ()
        self._twin_warned = False  # the NT pair's near-twin warning is logged once
        self.method = rules.settable("method", "mf", check=self._check_method, apply=self._apply_model_setup)
        self.high_frequency = rules.settable("high_frequency", 0.0, check=at_least(0.0))
        self.low_frequency = rules.settable("low_frequency", 0.0, check=at_least(0.0))
        self.min_confidence = rules.settable("min_confidence", DEFAULT_MIN_CONFIDENCE, check=within(0.0, 1.0))
        self.max_pixels = rules.settable("max_pixels", DEFAULT_MAX_PIXELS, check=at_least(1))
        self.camera_shape: tuple[int, int] | None = None  # (H, W) from /camera/camera_info
        self.consensus = rules.settable("consensus", False, check=self._check_consensus,
                                        apply=self._apply_model_setup)
        # declared last: a start-up model that cannot be loaded is named as parameter model (not consensus)
        self.model_path = rules.settable("model", "none", check=self._check_model, apply=self._apply_model_setup)
        self._prepared: _ModelSetup | None = None
        self._use(_model_setup(self.method, self.model_path, self.consensus))
        self.scans_published = 0
        self.scans_rejected = 0
        self.pixels_nan = 0
        self.pixels_low_confidence = 0
        self.scans_without_model = 0

        self.absolute_publisher = self.create_publisher(AbsolutePhase, "/scanner/absolute_phase", 10)
        self.intensity_publisher = self.create_publisher(Image, "/scanner/intensity", 10)
        self.status_publisher = self.create_publisher(ScanStatus, "/scanner/status", STATUS_QOS)
        self.scan_failures = ScanFailures(self, self.status_publisher)  # an exception in a scan fails that scan

        self.phase_subscription = self.create_subscription(PhaseMaps, "/scanner/phase", self.on_phase_maps, 10)
        self.info_subscription = self.create_subscription(CameraInfo, "/camera/camera_info", self.on_camera_info,
                                                          LATCHED_QOS, publishers=SOLE_PUBLISHER)  # the camera's
        self.decode_errors = DecodeErrorCount(self.phase_subscription)

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_camera_info(self, msg: CameraInfo) -> None:
        """The camera's size: every later PhaseMaps must have it."""
        if msg.height > 0 and msg.width > 0:
            self.camera_shape = (int(msg.height), int(msg.width))

    @fails_the_scan(lambda msg: msg.sequence_id)
    def on_phase_maps(self, msg: PhaseMaps) -> None:
        """Unwrap one scan; a scan the method cannot unwrap is reported, and the node goes on."""
        started_s = time.monotonic()
        self._scan_frequencies = tuple(float(f) for f in msg.frequencies)
        try:
            result, high, nan_pixels, model_note = self._unwrap(msg)
        except ValueError as exc:
            self.scans_rejected += 1
            reason = f"cannot unwrap scan {msg.sequence_id} ({self.method}): {exc}"
            self.get_logger().warning(reason)
            self._status(msg, ScanStatus.ERROR, "failed", reason, started_s)
            return
        f_h = float(msg.frequencies[high])
        valid, low_confidence = self._valid_pixels(result, msg.valid, f_h)
        invalid = ~valid
        absolute_phase, fringe_order, valid_out, reliability = self._message_arrays(result, valid, invalid)
        absolute = AbsolutePhase(
            header=msg.header, sequence_id=msg.sequence_id, frequency=f_h, fringe_axis=msg.fringe_axis,
            projector_width=msg.projector_width, projector_height=msg.projector_height,
            absolute_phase=absolute_phase, fringe_order=fringe_order, valid=valid_out, reliability=reliability,
            method="dptpu" if self.model is not None and not model_note else self.method)
        # the cloud's intensity: the unwrapped frequency's modulation (a view of the received maps, sent without a
        # copy), so the cloud node takes 1.2 MB a 640x480 scan instead of the whole PhaseMaps (5.2 MB)
        self.intensity_publisher.publish(Image.from_array(msg.modulation[high], "32FC1", header=msg.header))
        self.absolute_publisher.publish(absolute)
        self.scans_published += 1
        level, reasons = ScanStatus.OK, []
        if model_note:
            self.scans_without_model += 1
            reasons.append(model_note)
        if low_confidence:
            self.pixels_low_confidence += low_confidence
            reasons.append(f"{low_confidence} pixels below min_confidence {self.min_confidence:g} dropped")
        if nan_pixels:
            self.pixels_nan += nan_pixels
            level = ScanStatus.WARN
            reasons.append(f"{nan_pixels} pixels marked valid had NaN phase; treated as invalid")
            self.get_logger().warning(f"scan {msg.sequence_id}: {reasons[-1]}")
        self._status(msg, level, "processing", "; ".join(reasons), started_s,
                     valid_pixels=int(np.count_nonzero(valid)), total_pixels=int(valid.size))

    # -- parameters (method, model and consensus are checked together) --------------------------------------------

    def _check_method(self, method: str) -> str | None:
        if method not in PHASE_SEQUENCE_METHODS:  # alone, so that a bad start-up method is named as such
            raise ValueError(f"parameter method must be one of {', '.join(PHASE_SEQUENCE_METHODS)}; got {method!r}")
        if self._scan_frequencies:  # at run time, with scans arriving: refused when it cannot unwrap them
            try:
                select_frequencies(method, self._scan_frequencies, high=self._rules.value("high_frequency") or None,
                                   low=self._rules.value("low_frequency") or None,
                                   options=("high_frequency", "low_frequency"))
            except ValueError as exc:
                raise ValueError(f"method {method} cannot unwrap the scans arriving now: {exc}") from None
        if not self.has_parameter("model"):
            return None
        return self._prepare(method, self._rules.value("model"), self._rules.value("consensus"))

    def _check_model(self, model_path: str) -> str | None:
        return self._prepare(self._rules.value("method"), model_path, self._rules.value("consensus"))

    def _check_consensus(self, consensus: bool) -> str | None:
        if not self.has_parameter("model"):
            return None
        return self._prepare(self._rules.value("method"), self._rules.value("model"), consensus)

    def _prepare(self, method: str, model_path: str, consensus: bool) -> str | None:
        """Make (load) the setup of a new method, model or consensus before it is applied; ValueError refuses.
        (While the three are being declared the checks wait: ``__init__`` makes the first setup once all are.)"""
        self._prepared = _model_setup(method, model_path, consensus)
        return None

    def _apply_model_setup(self, _value) -> None:
        """Use the setup :meth:`_prepare` made, from the next scan."""
        if self._prepared is not None:
            self._use(self._prepared)
            self._prepared = None

    def _use(self, setup: _ModelSetup) -> None:
        self.method, self.consensus, self.auto_model = setup.method, setup.consensus, setup.auto
        self.model_path, self.model, self.refine_order = setup.model_path, setup.model, setup.refine_order

    # -- helpers ---------------------------------------------------------------------------------------------

    def _valid_pixels(self, result: tpu.Unwrapped, valid_in: np.ndarray, f_h: float) -> tuple[np.ndarray, int]:
        """``(valid (H, W) bool, pixels dropped below min_confidence)``: valid in the PhaseMaps and for the method,
        on the projector (``0 <= Psi < 2*pi*f_h``) and at least ``min_confidence``; in place, a few passes over
        (H, W)."""
        valid = np.logical_and(result.valid, valid_in)
        with np.errstate(invalid="ignore"):  # NaN phase where the method refused a pixel: False
            valid &= result.absolute_phase >= 0.0
            valid &= result.absolute_phase < _TWO_PI * f_h
        if self.min_confidence <= 0:  # reliability is in [0, 1] (0 where invalid): >= 0 always holds
            return valid, 0
        return confident(result.reliability, valid, self.min_confidence)

    def _message_arrays(self, result: tpu.Unwrapped, valid: np.ndarray, invalid: np.ndarray) -> list[np.ndarray]:
        """The AbsolutePhase's ``absolute_phase`` (NaN), ``fringe_order`` (0), ``valid`` and ``reliability`` (0), the
        fill where ``invalid``: written once into a loaned shared-memory segment, published without a copy; without
        shared memory, the result's own arrays masked in place (ZeroMQ sends them without a copy)."""
        shape = valid.shape
        specs = [(shape, np.float32), (shape, np.int32), (shape, np.bool_), (shape, np.float32)]
        if not self.absolute_publisher.can_loan_messages(sum(np.dtype(dtype).itemsize for _, dtype in specs)
                                                         * valid.size):
            return [_masked_in_place(result.absolute_phase, invalid, np.nan, np.float32),
                    _masked_in_place(result.fringe_order, invalid, 0, np.int32), valid,
                    _masked_in_place(result.reliability, invalid, 0.0, np.float32)]
        arrays = self.absolute_publisher.borrow_loaned_arrays(specs)
        for out, values, fill in zip(arrays[:2], (result.absolute_phase, result.fringe_order), (np.nan, 0)):
            _masked_into(out, values, invalid, fill)
        np.copyto(arrays[2], valid)
        _masked_into(arrays[3], result.reliability, invalid, 0.0)
        return arrays

    def _unwrap(self, msg: PhaseMaps):
        """``(Unwrapped, index of the high frequency, NaN pixels marked valid, why no model)``; ValueError for
        unusable maps."""
        self._check_shape(msg.valid.shape)  # before any buffer of the scan's size is allocated
        indices = select_frequencies(self.method, msg.frequencies, high=self.high_frequency or None,
                                     low=self.low_frequency or None, options=("high_frequency", "low_frequency"))
        phases = [msg.phases[i] for i in indices]  # (H, W) float32 each
        frequencies = [float(msg.frequencies[i]) for i in indices]
        valid = _finite(msg.valid, phases)
        nan_pixels = int(np.count_nonzero(msg.valid & ~valid))
        if self.method == "heterodyne":
            result = tpu.unwrap_heterodyne(phases, frequencies, valid=valid)
        elif self.method == "mf":  # float32 maps in and out: Eq. (5) in float32
            result = tpu.unwrap_mf_float32(phases[0], phases[1], frequencies[0], frequencies[1], valid=valid)
        else:
            extent = msg.extent_px if self.method == "nt" else None
            if self.method == "nt" and not extent:
                raise ValueError("nt needs the projector extent; the PhaseMaps has projector size 0 (unknown)")
            result = tpu.unwrap(self.method, phases[0], phases[1], frequencies[0], frequencies[1], extent=extent,
                                valid=valid)
        note = ""
        if self.model is not None and self.auto_model:
            # with the model only: dptpu.models is optional in a build
            from dptpu.models.refine import DEFAULT_MAX_PERIODS_PER_PIXEL, fringe_density

            density = fringe_density(phases[0], valid)
            if density > DEFAULT_MAX_PERIODS_PER_PIXEL:
                note = (f"no model: fringes of {density:.2f} periods per camera pixel, more than the "
                        f"{DEFAULT_MAX_PERIODS_PER_PIXEL:g} the shipped model serves")
        if self.model is not None and self.refine_order is not None and not note:  # DP-TPU (the paper's Fig. 8b)
            floor = None  # the agreement's rounding floor, as dptpu unwrap applies it, where the maps carry their steps
            if len(msg.steps) == len(msg.frequencies):
                high, low = indices[0], indices[1]
                floor = integer_frames_floor(msg.modulation[high], msg.modulation[low], int(msg.steps[high]),
                                             int(msg.steps[low]), frequencies[0], frequencies[1])
            refinement = self.refine_order(self.model, self.method, phases[0], phases[1], result.fringe_order,
                                           frequencies[0], frequencies[1], result.valid, consensus=self.consensus,
                                           consistency_floor=floor, modulation=msg.modulation[indices[0]])
            result = refined(result, refinement.absolute_phase, refinement.order, refinement.confidence)
        elif self.method == "nt":  # no confidence where neither pixel nor region tells the order from a near-twin
            twins = twin_ambiguous(result.absolute_phase, phases[1], frequencies[0], frequencies[1], result.valid,
                                   modulation=msg.modulation[indices[0]])
            result = dataclasses.replace(result, reliability=np.where(twins, 0.0, result.reliability))
        if self.method == "nt" and not self._twin_warned:  # the pair's near-twin within the noise's reach: once
            warning = scan_twin_warning(result.absolute_phase, phases[1], frequencies[0], frequencies[1],
                                        result.valid)
            if warning is not None:
                self._twin_warned = True
                self.get_logger().warning(warning)
        return result, indices[0], nan_pixels, note

    def _check_shape(self, shape: tuple[int, ...]) -> None:
        """ValueError for a scan that is not the camera's size (once a CameraInfo gave it) or has more than
        ``max_pixels`` pixels (before)."""
        height, width = shape
        if self.camera_shape is not None:
            if (height, width) != self.camera_shape:
                raise ValueError(f"the maps are {width}x{height} but /camera/camera_info says the camera is "
                                 f"{self.camera_shape[1]}x{self.camera_shape[0]}; refused before unwrapping")
        elif height * width > self.max_pixels:
            raise ValueError(f"the maps are {width}x{height} = {height * width} pixels, more than max_pixels "
                             f"{self.max_pixels} (no CameraInfo has given the camera's size); refused before "
                             f"unwrapping")

    def _status(self, msg, level, state, reason, started_s, **counts) -> None:
        self.status_publisher.publish(scan_status(
            self, msg.sequence_id, level, state, reason, decode_errors=self.decode_errors.since_last_report(),
            duration_s=time.monotonic() - started_s, **counts))


class _ModelSetup(NamedTuple):
    """What ``method``, ``model`` and ``consensus`` make together (:func:`_model_setup`)."""

    method: str
    model_path: str  # "shipped" or "none" for auto
    auto: bool
    consensus: bool
    model: Any  # dptpu.models.inference.FringeOrderModel or None (an optional part of a build)
    refine_order: Callable[..., Any] | None  # dptpu.models.refine.refinement (returns a Refinement)


def _model_setup(method: str, model_path: str, consensus: bool) -> _ModelSetup:
    """Check ``method``, ``model`` and ``consensus`` together and load the model; ValueError (or ImportError) when
    they do not go together."""
    if method not in PHASE_SEQUENCE_METHODS:
        raise ValueError(f"parameter method must be one of {', '.join(PHASE_SEQUENCE_METHODS)}; got {method!r}")
    auto = model_path == "auto"
    if auto:  # the packaged model where it serves the method; the fringes are judged per scan
        model_path = "shipped" if method != "heterodyne" else "none"
    if model_path not in ("", "none") and method == "heterodyne":
        raise ValueError("parameter model refines a two-frequency method (mf, mw or nt), as the network was "
                         "trained; got method heterodyne")
    model = load_model(model_path) if not auto or _shipped_model_exists() else None
    if auto and model is not None and not model.serves(method):
        model = None
    if model is not None and not model.serves(method):
        raise ValueError(f"parameter model {model_path!r} was trained for method(s) "
                         f"{', '.join(model.trained_methods)}; got method {method}")
    if consensus and model is None:
        raise ValueError("parameter consensus post-processes the network's fringe order; set model (a DP-TPU "
                         "model file or shipped) or consensus:=false")
    return _ModelSetup(method, model_path, auto, consensus, model,
                       _load_refine_order() if model is not None else None)


def _masked_in_place(values: np.ndarray, invalid: np.ndarray, fill, dtype) -> np.ndarray:
    """``values`` (H, W) as ``dtype`` with ``fill`` where ``invalid``: in place when it already has that dtype (the
    arrays of one scan's result, which nothing else holds), else one new array."""
    if values.dtype == dtype and values.flags.writeable:
        np.copyto(values, fill, where=invalid)
        return values
    out = np.full(values.shape, fill, dtype=dtype)
    np.copyto(out, values, where=~invalid, casting="unsafe")
    return out


def _masked_into(out: np.ndarray, values: np.ndarray, invalid: np.ndarray, fill) -> None:
    """``out`` (H, W) = ``values`` cast to its dtype, ``fill`` where ``invalid`` (what a NaN or an order of an invalid
    pixel becomes in the cast does not matter: it is overwritten)."""
    with np.errstate(invalid="ignore"):
        np.copyto(out, values, casting="unsafe")
    np.copyto(out, fill, where=invalid)


def _finite(valid, phases) -> np.ndarray:
    """``valid`` restricted to pixels whose phases are all finite: a NaN is an invalid pixel, never an error."""
    mask = np.array(valid, dtype=bool)
    for phase in phases:
        mask &= np.isfinite(phase)
    return mask


def load_model(path: str):
    """The DP-TPU fringe-order model of ``path`` (None for ``"none"``; ``"shipped"``: the packaged model).

    Returns
    -------
    dptpu.models.inference.FringeOrderModel or None

    Raises
    ------
    ImportError
        When :mod:`dptpu.models.inference` (the onnxruntime runner of the DP-TPU network) is not in this build.
    ValueError
        For a model file that is missing or not a dptpu model (``ModelLoadError``), or no shipped model.
    """
    if path in ("", "none"):
        return None
    try:
        from dptpu.models import inference  # an optional part of a build (onnxruntime only, never torch)
    except ImportError as exc:
        raise ImportError(f"parameter model={path!r} needs the module dptpu.models.inference (the DP-TPU network "
                          f"run by onnxruntime), which this build lacks ({exc}); set model:=none for classical "
                          "unwrapping") from exc
    if path == "shipped":
        shipped = inference.shipped_model_path()
        if shipped is None:
            raise ValueError(f"parameter model='shipped': this build has no shipped model ({inference.SHIPPED_MODEL}); "
                             "pass a model file or model:=none")
        return inference.FringeOrderModel.load(shipped, threads=1)
    return inference.FringeOrderModel.load(path, threads=1)


def _load_refine_order() -> Callable[..., Any]:
    """:func:`dptpu.models.refine.refinement`: the NT prior, the consensus, the network's confidence and the absolute
    phase (numpy, OpenCV, onnxruntime)."""
    # with the model only: dptpu.models is optional in a build
    from dptpu.models.refine import refinement

    return refinement


def _shipped_model_exists() -> bool:
    """Whether this build has the packaged model (``model:=auto`` runs classical without one)."""
    try:
        from dptpu.models import inference  # an optional part of a build (onnxruntime only, never torch)
    except ImportError:
        return False
    return inference.shipped_model_path() is not None


def refined(result: tpu.Unwrapped, absolute_phase: np.ndarray, order: np.ndarray,
            confidence: np.ndarray | None = None) -> tpu.Unwrapped:
    """``result`` with the network's fringe order ``order`` (H, W) and its absolute phase ``Psi = psi_h + 2*pi*k``
    (Eq. (3); :attr:`dptpu.models.refine.Refinement.absolute_phase`), NaN where not valid; its ``reliability``
    becomes ``confidence`` (the network's, :func:`dptpu.fpp.confidence.network_confidence`) when given."""
    reliability = result.reliability if confidence is None else np.where(result.valid, confidence, 0.0)
    return tpu.Unwrapped(fringe_order=order, absolute_phase=np.where(result.valid, absolute_phase, np.nan),
                         valid=result.valid, reliability=reliability, n_rejected=result.n_rejected)


def main(argv=None) -> int:
    """``python -m dptpu.nodes.unwrap [--ros-args ...]``: run the node until Ctrl-C or SIGTERM."""
    return run_node("unwrap", UnwrapNode, argv)

