"""Phase node: assembles the fringe frames of each scan and publishes its wrapped phase maps.

Frames are collected per ``sequence_id`` (:mod:`dptpu.nodes.phase.sequence_assembler`); a complete scan gives one
wrapped phase, modulation and quality mask per frequency by least squares (Eq. (2) of the paper). The node feeds
each frame to :class:`dptpu.fpp.scan_phase.IncrementalScanPhase` as it arrives (an entry's sums are computed the
moment its last frame is in), so after a scan's last frame only its last entry is left; a scan placed otherwise
than its final layout falls back to :func:`dptpu.fpp.scan_phase.scan_phase_maps` on the stacked frames (why not
sums accumulated frame by frame: docs/benchmarks.md, Run 5). An incomplete scan is
dropped ``timeout_s`` after its first frame, an inconsistent one at once; either way a ``ScanStatus``
(ERROR, ``failed``) says why, and frames of two scans are never mixed.

Topics (defaults; remappable)

=============================== ================= ===== ==============================================
topic                           type              dir   notes
=============================== ================= ===== ==============================================
``/camera/image_raw``           FringeFrame       in    best effort, depth ``frame_queue_depth`` (not with
                                                        ``frame_bursts``)
``/camera/frame_bursts``        FringeBurst       in    with ``frame_bursts``, instead of the frames: best effort,
                                                        depth ``frame_queue_depth`` messages
``/projector/pattern_sequence`` PatternSequence   in    transient local, depth 1: the scan layout (optional)
``/scanner/phase``              PhaseMaps         out   reliable, depth 10
``/scanner/texture``            Image             out   reliable, depth 10; 32FC1, the scan's texture in DN
                                                        (:mod:`dptpu.fpp.texture`: the white frame minus the black
                                                        one when the sequence has them, else the mean intensity
                                                        ``A`` of Eq. (2) over the entries), published just before
                                                        its PhaseMaps with the same header
``/scanner/status``             ScanStatus        out   one per scan: ``processing`` (OK) or ``failed``
=============================== ================= ===== ==============================================

Parameters

======================= ======== ================================================================================
name                    default  meaning
======================= ======== ================================================================================
``timeout_s``           2.0      seconds from a scan's first frame until it is dropped as incomplete
``max_pending_scans``   4        scans assembled at once; a newer one drops the oldest ("superseded")
``min_modulation``      5.0      smallest fringe modulation B of a valid pixel, camera digital numbers
``saturation_level``    0.0      a pixel with any frame ``>=`` this is invalid; 0 = the image dtype's maximum
``max_noise_ratio``     5.0      a pixel whose phase noise, from its own fit (entries of 5 or more steps), is this
                                 many times the scan's median or more is invalid (:mod:`dptpu.fpp.fringe_noise`);
                                 0 = no such test
``shift_sign``          -1       used until a PatternSequence arrives: image n is A + B cos(phi + sign*2*pi*n/N)
``fringe_axis``         "x"      used until a PatternSequence arrives
``projector_width``     0        used until a PatternSequence arrives (0 = unknown)
``projector_height``    0        used until a PatternSequence arrives (0 = unknown)
``frame_queue_depth``   100      frames the subscription may queue (at least the patterns of two scans)
``frame_bursts``        false    take the frames as FringeBursts (``/camera/frame_bursts``: an entry's frames in one
                                 message, the sim's and camera's ``frame_bursts:=true``) instead of FringeFrames
``rig``                 ""       a dptpu-rig/1 file whose ``projector.phase_response`` (``dptpu calibrate
                                 response``) corrects the wrapped phase of each entry whose step count it holds
                                 (:meth:`dptpu.fpp.phase_harmonics.ProjectorPhaseResponse.correct`); "" or a rig
                                 without it: the phases as computed
======================= ======== ================================================================================

While no frame comes, the node checks once a second that its frame topic has a publisher: where only the other one
has (the camera side's ``frame_bursts`` set otherwise), it logs one warning naming both topics, the publishers and
the parameter (:mod:`dptpu.nodes.phase.frame_topic_check`).

``min_modulation``, ``saturation_level`` and ``max_noise_ratio`` apply from the next scan (``dptpu param set``),
checked as at start-up; the others are read-only (``param set`` is refused; restart the node to change them).

Run: ``python -m dptpu.nodes.phase --ros-args -p timeout_s:=1.0``, or ``pkg: dptpu, exec: phase`` in a
launch file. Conventions: ``docs/messages.md``; node design: ``docs/nodes.md``.
"""
from __future__ import annotations

import math
import time

import numpy as np

from dptpu.fpp.calibration import load_rig
from dptpu.fpp.fringe_noise import DEFAULT_MAX_NOISE_RATIO
from dptpu.fpp.scan_phase import IncrementalScanPhase, scan_phase_maps
from dptpu.fpp.texture import texture_image
from dptpu.graph.known_publishers import SOLE_PUBLISHER
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least
from dptpu.graph.qos import QoSProfile, ReliabilityPolicy
from dptpu.messages import (
    FringeBurst,
    FringeFrame,
    Header,
    Image,
    PatternSequence,
    PhaseMaps,
    ScanStatus,
    Time,
)
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import (
    DEFAULT_FRAME_ID,
    LATCHED_QOS,
    STATUS_QOS,
    DecodeErrorCount,
    ScanFailures,
    fails_the_scan,
    scan_status,
)

from .frame_topic_check import FrameTopicCheck
from .sequence_assembler import (
    AssembledScan,
    DroppedScan,
    FrameInfo,
    RejectedFrame,
    ScanLayout,
    SequenceAssembler,
)

__all__ = ["PhaseNode", "main"]


def _noise_ratio(value) -> str | None:
    """The check of ``max_noise_ratio``: 0 (no test) or above 1."""
    return None if value == 0 or value > 1 else f"must be 0 (no test) or > 1; got {value}"


class PhaseNode(Node):
    """Fringe frames -> PhaseMaps, one per complete scan (see the module docstring).

    Counters (for tests and introspection): ``frames_received``, ``scans_published``, ``scans_dropped``,
    ``frames_rejected``.
    """

    def __init__(self, node_name: str = "phase", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        fixed = "sets the assembler up; restart the node to change it"
        self.timeout_s = rules.read_only("timeout_s", 2.0, description=fixed)
        self.max_pending_scans = rules.read_only("max_pending_scans", 4, description=fixed)
        self.min_modulation = rules.settable("min_modulation", 5.0, check=at_least(0.0))
        self.saturation_level = rules.settable("saturation_level", 0.0, check=at_least(0.0))
        self.max_noise_ratio = rules.settable("max_noise_ratio", DEFAULT_MAX_NOISE_RATIO, check=_noise_ratio)
        layout = "the layout without a PatternSequence (the projector's, when it comes, wins)"
        shift_sign = rules.read_only("shift_sign", -1, description=layout)
        fringe_axis = rules.read_only("fringe_axis", "x", description=layout)
        projector_size = (rules.read_only("projector_width", 0, description=layout),
                          rules.read_only("projector_height", 0, description=layout))
        frame_queue_depth = self.frame_queue_depth = rules.read_only("frame_queue_depth", 100,
                                                                     description="the subscription's QoS depth")
        frame_bursts = rules.read_only("frame_bursts", False, description="sets the frames' subscription up")
        if frame_queue_depth < 1:
            raise ValueError(f"parameter frame_queue_depth must be >= 1; got {frame_queue_depth}")
        rig_path = rules.read_only("rig", "", description="its projector.phase_response corrects the phases; "
                                                          "restart the node to change it")
        self.phase_response = load_rig(rig_path).phase_response if rig_path else None
        if self.phase_response is not None:
            held = ", ".join(map(str, self.phase_response.steps))
            self.get_logger().info(f"projector phase response of {rig_path}: {held}-step phases corrected")
        self.assembler = SequenceAssembler(timeout_s=self.timeout_s, max_pending_scans=self.max_pending_scans,
                                           shift_sign=shift_sign, fringe_axis=fringe_axis,
                                           projector_size=projector_size)
        self.frames_received = 0
        self.scans_published = 0
        self.scans_dropped = 0
        self.frames_rejected = 0
        self._sums: dict[int, IncrementalScanPhase] = {}  # sequence_id -> the Eq. (2) sums of a scan being assembled
        self._frame_id = DEFAULT_FRAME_ID  # the camera's, from its latest frame

        self.phase_publisher = self.create_publisher(PhaseMaps, "/scanner/phase", 10)
        self.texture_publisher = self.create_publisher(Image, "/scanner/texture", 10)
        self.status_publisher = self.create_publisher(ScanStatus, "/scanner/status", STATUS_QOS)
        self.scan_failures = ScanFailures(self, self.status_publisher)  # an exception in a scan fails that scan

        frame_qos = QoSProfile(depth=frame_queue_depth, reliability=ReliabilityPolicy.BEST_EFFORT)
        if frame_bursts:
            self.frame_subscription = self.create_subscription(FringeBurst, "/camera/frame_bursts", self.on_burst,
                                                               frame_qos)
        else:
            self.frame_subscription = self.create_subscription(FringeFrame, "/camera/image_raw", self.on_frame,
                                                               frame_qos)
        self.sequence_subscription = self.create_subscription(PatternSequence, "/projector/pattern_sequence",
                                                              self.on_pattern_sequence, LATCHED_QOS,
                                                              publishers=SOLE_PUBLISHER)  # the projector's only
        self.decode_errors = DecodeErrorCount(self.frame_subscription, self.sequence_subscription)
        self.expiry_timer = self.create_timer(min(0.25, self.timeout_s / 4), self.on_timer)
        other = self.resolve_topic_name("/camera/image_raw" if frame_bursts else "/camera/frame_bursts")
        self.frame_topic_check = FrameTopicCheck(self.frame_subscription.topic_name, other, bool(frame_bursts))
        self._frames_at_check = -1  # frames_received at the last frame topic check (-1: none yet)
        self.frame_topic_timer = self.create_timer(1.0, self.on_frame_topic_timer)

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_pattern_sequence(self, msg: PatternSequence) -> None:
        """Lay out the scans that start from now on by the projector's PatternSequence."""
        try:
            layout = ScanLayout.from_pattern_sequence(msg)
        except ValueError as exc:
            self.get_logger().warning(f"ignoring PatternSequence: {exc}")
            return
        self.assembler.set_layout(layout)
        self.get_logger().info(f"scan layout: frequencies {list(layout.frequencies)}, steps {list(layout.steps)}, "
                               f"shift_sign {layout.shift_sign}, fringe_axis {layout.fringe_axis}")

    @fails_the_scan(lambda msg: msg.trigger.sequence_id)
    def on_frame(self, msg: FringeFrame) -> None:
        """Add one frame; publish the PhaseMaps of a scan it completes, a ScanStatus for a scan it fails."""
        self.frames_received += 1
        now_s = time.monotonic()
        trigger = msg.trigger
        try:
            image = msg.image.to_array()  # (H, W) view of the received frame
            if msg.image.encoding not in ("mono8", "mono16"):
                raise ValueError(f"image encoding must be mono8 or mono16; got {msg.image.encoding!r}")
        except ValueError as exc:
            self._report(self.assembler.fail(trigger.sequence_id,
                                             f"frame of pattern {trigger.pattern_index} unreadable: {exc}", now_s))
            return
        self._frame_id = msg.image.header.frame_id or DEFAULT_FRAME_ID
        self._add(trigger, image, msg.image.header.stamp.to_ns(), now_s)

    @fails_the_scan(lambda msg: msg.triggers[0].sequence_id if msg.triggers else 0)
    def on_burst(self, msg: FringeBurst) -> None:
        """Add a burst's frames, as :meth:`on_frame` adds one; a frame's stamp is its Trigger's, the last one's the
        burst's (its exposure start)."""
        now_s = time.monotonic()
        if not msg.triggers:
            self.frames_rejected += 1
            self.get_logger().warning("an empty FringeBurst (no Trigger, no frame) refused", throttle_duration_sec=1.0)
            return
        self.frames_received += len(msg.triggers)
        try:
            if msg.image.encoding not in ("mono8", "mono16"):
                raise ValueError(f"image encoding must be mono8 or mono16; got {msg.image.encoding!r}")
            frames = msg.frames()  # (N, H, W) view of the received burst
        except ValueError as exc:
            first = msg.triggers[0]
            self._report(self.assembler.fail(first.sequence_id, f"burst of patterns {first.pattern_index}.."
                                             f"{msg.triggers[-1].pattern_index} unreadable: {exc}", now_s))
            return
        self._frame_id = msg.image.header.frame_id or DEFAULT_FRAME_ID
        last = len(msg.triggers) - 1
        for index, (trigger, image) in enumerate(zip(msg.triggers, frames)):
            stamp = msg.image.header.stamp if index == last else trigger.header.stamp
            self._add(trigger, image, stamp.to_ns(), now_s)

    def _add(self, trigger, image: np.ndarray, stamp_ns: int, now_s: float) -> None:
        """Add one frame (H, W) to its scan and to its Eq. (2) sums; report what it completes or fails."""
        frame = FrameInfo(sequence_id=trigger.sequence_id, pattern_index=trigger.pattern_index,
                          pattern_count=trigger.pattern_count, frequency=trigger.frequency, steps=trigger.steps,
                          step=trigger.step, image=image, stamp_ns=stamp_ns, kind=trigger.kind)
        events = self.assembler.add(frame, now_s)
        slot = self.assembler.slot(frame.sequence_id, frame.pattern_index)  # None unless kept by a pending scan
        if slot is not None:
            self._sums.setdefault(frame.sequence_id, IncrementalScanPhase()).add(frame.pattern_index, image, slot)
        for event in events:
            self._report(event)

    def on_timer(self) -> None:
        """Drop the scans that timed out."""
        for event in self.assembler.expire(time.monotonic()):
            self._report(event)

    def on_frame_topic_timer(self) -> None:
        """Once a second while no frame comes: say so when the camera side publishes on the other frame topic."""
        if self.frames_received == self._frames_at_check:
            publishers = [[info.node for info in self.get_publishers_info_by_topic(topic)]
                          for topic in (self.frame_topic_check.taken, self.frame_topic_check.other)]
            warning = self.frame_topic_check.check(*publishers)
            if warning:
                self.get_logger().warning(warning)
        self._frames_at_check = self.frames_received

    # -- helpers ---------------------------------------------------------------------------------------------

    def _report(self, event) -> None:
        if isinstance(event, AssembledScan):
            self._publish_scan(event)
        elif isinstance(event, DroppedScan):
            self._sums.pop(event.sequence_id, None)
            self.scans_dropped += 1
            reason = event.reason
            frames = self.frame_subscription
            if frames.dropped_count:  # frames this node never saw: say where they went (queue or transport)
                reason += (f" (frames lost so far: {frames.queue_dropped_count} dropped from the full queue of "
                           f"{self.frame_queue_depth}, {frames.lost_count} in transport)")
            self.get_logger().warning(f"scan {event.sequence_id} dropped: {reason}")
            self._status(event.sequence_id, ScanStatus.ERROR, "failed", reason, event.first_arrival_s,
                         frames_expected=event.frames_expected, frames_received=event.frames_received,
                         frames_dropped=event.frames_received)
        elif isinstance(event, RejectedFrame):
            self.frames_rejected += 1
            self.get_logger().warning(f"frame refused ({self.frames_rejected} so far): {event.reason}",
                                      throttle_duration_sec=1.0)

    def _publish_scan(self, scan: AssembledScan) -> None:
        saturation = self.saturation_level if self.saturation_level > 0 else None
        sums = self._sums.pop(scan.sequence_id, None) or IncrementalScanPhase()
        slots = scan.slots()
        layout = scan.layout
        # the maps and the texture are computed in place in loaned shared-memory segments and published without a
        # copy (plain arrays where there is no shared memory)
        phase_maps, texture_out = self._borrow_maps(len(scan.images), scan.images[0][0].shape)
        try:
            pattern_index = 0
            for images in scan.images:
                for image in images:  # the frame that completed the scan (normally the only one not added yet)
                    if pattern_index not in sums.slots:
                        sums.add(pattern_index, image, slots[pattern_index])
                    pattern_index += 1
            maps = sums.maps(slots, min_modulation=self.min_modulation, saturation_level=saturation,
                             max_noise_ratio=self.max_noise_ratio, out=phase_maps)
            background = sums.background(out=None if scan.references.get("white") is not None
                                         else texture_out)
            if maps is None:
                computed = scan_phase_maps(scan.stacks, layout.phase_offsets, shift_sign=layout.shift_sign,
                                           min_modulation=self.min_modulation, saturation_level=saturation,
                                           max_noise_ratio=self.max_noise_ratio)
                for target, values in zip(phase_maps, computed):
                    np.copyto(target, values)
                maps = phase_maps
                background = np.mean([stack.mean(axis=0, dtype=np.float32) for stack in scan.stacks], axis=0)
            phases, modulation, valid = maps
            if self.phase_response is not None:
                self._correct_in_place(phases, layout)
            texture = texture_image(background=background, white=scan.references.get("white"),
                                    black=scan.references.get("black"))  # (H, W) float32 DN
            if texture is not texture_out:
                np.copyto(texture_out, texture)
        except ValueError as exc:
            self.phase_publisher.return_loaned_arrays(phase_maps)
            self.texture_publisher.return_loaned_arrays([texture_out])
            self._report(DroppedScan(scan.sequence_id, f"phase computation refused the frames: {exc}",
                                     scan.frame_count, scan.frame_count, scan.first_arrival_s))
            return
        header = Header(stamp=Time.from_ns(scan.last_stamp_ns), frame_id=self._frame_id)
        self.texture_publisher.publish(Image.from_array(texture_out, "32FC1", header=header))
        self.phase_publisher.publish(PhaseMaps(
            header=header, sequence_id=scan.sequence_id, fringe_axis=layout.fringe_axis,
            projector_width=layout.projector_size[0], projector_height=layout.projector_size[1],
            frequencies=np.asarray(layout.frequencies, dtype=np.float64), phases=phases, modulation=modulation,
            valid=valid, steps=np.asarray(layout.steps, dtype=np.uint32)))
        self.scans_published += 1
        self._status(scan.sequence_id, ScanStatus.OK, "processing", "", scan.first_arrival_s,
                     frames_expected=scan.frame_count + len(scan.references),
                     frames_received=scan.frame_count + len(scan.references),
                     valid_pixels=int(np.count_nonzero(valid)), total_pixels=int(valid.size))

    def _borrow_maps(self, entries: int, shape: tuple[int, ...]) -> tuple[list[np.ndarray], np.ndarray]:
        """``([phases (F, H, W) float32, modulation (F, H, W) float32, valid (H, W) bool], texture (H, W)
        float32)``: arrays lent by the publishers (:meth:`dptpu.graph.publisher.Publisher.borrow_loaned_arrays`),
        in the order PhaseMaps encodes them, where a loan pays (``Publisher.can_loan_messages``); new arrays,
        which ZeroMQ sends without a copy, where it does not."""
        specs = [((entries, *shape), np.float32), ((entries, *shape), np.float32), (shape, np.bool_)]
        pixels = math.prod(shape)
        if self.phase_publisher.can_loan_messages(pixels * (8 * entries + 1)):
            maps = self.phase_publisher.borrow_loaned_arrays(specs)
        else:
            maps = [np.empty(spec_shape, dtype) for spec_shape, dtype in specs]
        if self.texture_publisher.can_loan_messages(pixels * 4):
            (texture,) = self.texture_publisher.borrow_loaned_arrays([(shape, np.float32)])
        else:
            texture = np.empty(shape, np.float32)
        return maps, texture

    def _correct_in_place(self, phases: np.ndarray, layout: ScanLayout) -> None:
        """Remove the projector's harmonic phase error from each entry of ``phases`` (F, H, W) whose step count the
        rig's response holds (others untouched)."""
        response = self.phase_response
        if response is None:
            return
        for index, (steps, offset) in enumerate(zip(layout.steps, layout.phase_offsets)):
            if response.for_steps(steps) is not None:
                phases[index] = response.correct(phases[index], steps, phase_offset=offset)

    def _status(self, sequence_id, level, state, reason, first_arrival_s, **counts) -> None:
        self.status_publisher.publish(scan_status(
            self, sequence_id, level, state, reason, decode_errors=self.decode_errors.since_last_report(),
            duration_s=max(0.0, time.monotonic() - first_arrival_s), **counts))


def main(argv=None) -> int:
    """``python -m dptpu.nodes.phase [--ros-args ...]``: run the node until Ctrl-C or SIGTERM."""
    return run_node("phase", PhaseNode, argv)

