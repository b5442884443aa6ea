"""Unwrap node: temporal phase unwrapping of each scan's wrapped phase maps into an absolute phase.

Classical methods from :mod:`dptpu.fpp.tpu` (the paper's Eqs. (3)-(9)); optionally the fringe order is then
refined by the DP-TPU network (``model``, run by :mod:`dptpu.models.inference` with onnxruntime).

Topics (defaults; remappable)

=========================== ============= ===== ===============================================
topic                       type          dir   notes
=========================== ============= ===== ===============================================
``/scanner/phase``          PhaseMaps     in    reliable, depth 10
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
=================== ========= ===================================================================================

Valid pixels: valid in the PhaseMaps, accepted by the method, at least ``min_confidence`` and on the
projector (``0 <= Psi < 2*pi*f``, as :func:`dptpu.fpp.reconstruct.unwrap_capture` requires). Run:
``python -m dptpu.nodes.unwrap --ros-args -p method:=nt``; design: ``docs/nodes.md``.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from dptpu.fpp import tpu
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE, confident
from dptpu.fpp.frequencies import select_frequencies
from dptpu.fpp.methods import PHASE_SEQUENCE_METHODS
from dptpu.graph.node import Node
from dptpu.messages import AbsolutePhase, Image, PhaseMaps, ScanStatus
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import STATUS_QOS, DecodeErrorCount, scan_status

__all__ = ["UnwrapNode", "load_model", "main", "refined"]

_TWO_PI = 2.0 * np.pi


class UnwrapNode(Node):
    """PhaseMaps -> AbsolutePhase (see the module docstring).

    Counters: ``scans_published``, ``scans_rejected``, ``pixels_nan`` (pixels marked valid whose phase was NaN),
    ``pixels_low_confidence`` (valid pixels dropped below ``min_confidence``), ``scans_without_model`` (``auto``
    scans the gate left classical).
    """

    def __init__(self, node_name: str = "unwrap", **node_options):
        super().__init__(node_name, **node_options)
        self.method = self.declare_parameter("method", "mf").value
        self.model_path = self.declare_parameter("model", "none").value
        self.high_frequency = self.declare_parameter("high_frequency", 0.0).value
        self.low_frequency = self.declare_parameter("low_frequency", 0.0).value
        self.min_confidence = self.declare_parameter("min_confidence", DEFAULT_MIN_CONFIDENCE).value
        self.consensus = self.declare_parameter("consensus", False).value
        if self.method not in PHASE_SEQUENCE_METHODS:
            raise ValueError(f"parameter method must be one of {', '.join(PHASE_SEQUENCE_METHODS)}; got "
                             f"{self.method!r}")
        if self.high_frequency < 0 or self.low_frequency < 0:
            raise ValueError("parameters high_frequency and low_frequency must be >= 0 (0 = default); got "
                             f"{self.high_frequency}, {self.low_frequency}")
        if not 0.0 <= self.min_confidence <= 1.0:
            raise ValueError(f"parameter min_confidence must be in [0, 1]; got {self.min_confidence}")
        self.auto_model = self.model_path == "auto"
        if self.auto_model:  # the packaged model where it serves the method; the fringes are judged per scan
            self.model_path = "shipped" if self.method != "heterodyne" else "none"
        if self.model_path not in ("", "none") and self.method == "heterodyne":
            raise ValueError("parameter model refines a two-frequency method (mf, mw or nt), as the network was "
                             "trained; got method heterodyne")
        self.model = load_model(self.model_path) if not self.auto_model or _shipped_model_exists() else None
        if self.auto_model and self.model is not None and not self.model.serves(self.method):
            self.model = None
        if self.model is not None and not self.model.serves(self.method):
            raise ValueError(f"parameter model {self.model_path!r} was trained for method(s) "
                             f"{', '.join(self.model.trained_methods)}; got method {self.method}")
        if self.consensus and self.model is None:
            raise ValueError("parameter consensus post-processes the network's fringe order; set model (a DP-TPU "
                             "model file or shipped) or consensus:=false")
        self.refine_order: Callable[..., tuple[np.ndarray, np.ndarray]] | None = (
            _load_refine_order() if self.model is not None else None)
        self.scans_published = 0
        self.scans_rejected = 0
        self.pixels_nan = 0
        self.pixels_low_confidence = 0
        self.scans_without_model = 0

        self.absolute_publisher = self.create_publisher(AbsolutePhase, "/scanner/absolute_phase", 10)
        self.intensity_publisher = self.create_publisher(Image, "/scanner/intensity", 10)
        self.status_publisher = self.create_publisher(ScanStatus, "/scanner/status", STATUS_QOS)

        self.phase_subscription = self.create_subscription(PhaseMaps, "/scanner/phase", self.on_phase_maps, 10)
        self.decode_errors = DecodeErrorCount(self.phase_subscription)

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_phase_maps(self, msg: PhaseMaps) -> None:
        """Unwrap one scan; a scan the method cannot unwrap is reported, and the node goes on."""
        started_s = time.monotonic()
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
        absolute = AbsolutePhase(
            header=msg.header, sequence_id=msg.sequence_id, frequency=f_h, fringe_axis=msg.fringe_axis,
            projector_width=msg.projector_width, projector_height=msg.projector_height,
            absolute_phase=_masked_in_place(result.absolute_phase, invalid, np.nan, np.float32),
            fringe_order=_masked_in_place(result.fringe_order, invalid, 0, np.int32), valid=valid,
            reliability=_masked_in_place(result.reliability, invalid, 0.0, np.float32),
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

    def _unwrap(self, msg: PhaseMaps):
        """``(Unwrapped, index of the high frequency, NaN pixels marked valid, why no model)``; ValueError for
        unusable maps."""
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
            order, confidence = self.refine_order(self.model, self.method, phases[0], phases[1], result.fringe_order,
                                                  frequencies[0], frequencies[1], result.valid,
                                                  consensus=self.consensus)
            result = refined(result, phases[0].astype(np.float64), order, confidence)
        return result, indices[0], nan_pixels, note

    def _status(self, msg, level, state, reason, started_s, **counts) -> None:
        self.status_publisher.publish(scan_status(
            self, msg.sequence_id, level, state, reason, decode_errors=self.decode_errors.since_last_report(),
            duration_s=time.monotonic() - started_s, **counts))


def _masked_in_place(values: np.ndarray, invalid: np.ndarray, fill, dtype) -> np.ndarray:
    """``values`` (H, W) as ``dtype`` with ``fill`` where ``invalid``: in place when it already has that dtype (the
    arrays of one scan's result, which nothing else holds), else one new array."""
    if values.dtype == dtype and values.flags.writeable:
        np.copyto(values, fill, where=invalid)
        return values
    out = np.full(values.shape, fill, dtype=dtype)
    np.copyto(out, values, where=~invalid, casting="unsafe")
    return out


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


def _load_refine_order() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """:func:`dptpu.models.refine.refine_order_and_confidence`: the NT prior, the consensus and the network's
    confidence (numpy, OpenCV, onnxruntime)."""
    # with the model only: dptpu.models is optional in a build
    from dptpu.models.refine import refine_order_and_confidence

    return refine_order_and_confidence


def _shipped_model_exists() -> bool:
    """Whether this build has the packaged model (``model:=auto`` runs classical without one)."""
    try:
        from dptpu.models import inference  # an optional part of a build (onnxruntime only, never torch)
    except ImportError:
        return False
    return inference.shipped_model_path() is not None


def refined(result: tpu.Unwrapped, psi_h: np.ndarray, order: np.ndarray,
            confidence: np.ndarray | None = None) -> tpu.Unwrapped:
    """``result`` with the network's fringe order ``order`` (H, W): ``Psi = psi_h + 2*pi*k`` (Eq. (3)); its
    ``reliability`` becomes ``confidence`` (the network's, :func:`dptpu.fpp.confidence.network_confidence`) when
    given."""
    reliability = result.reliability if confidence is None else np.where(result.valid, confidence, 0.0)
    return tpu.Unwrapped(fringe_order=order, absolute_phase=np.where(result.valid, psi_h + _TWO_PI * order, np.nan),
                         valid=result.valid, reliability=reliability, n_rejected=result.n_rejected)


def main(argv=None) -> int:
    """``python -m dptpu.nodes.unwrap [--ros-args ...]``: run the node until Ctrl-C or SIGTERM."""
    return run_node("unwrap", UnwrapNode, argv)

