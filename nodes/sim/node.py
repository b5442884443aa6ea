"""Sim node: stands in for the camera and the projector's optics, answering each Trigger with the twin's frame.

On each :class:`~dptpu.messages.Trigger` the node publishes the :class:`~dptpu.messages.FringeFrame` of that
pattern (the frame of the trigger's frequency and step) of the current scene, taken from the shipped Blender
renders of the twin (default), from live raycast renders (:mod:`dptpu.sim.raycast`), or from capture folders
(:mod:`dptpu.nodes.sim.source`). Scenes cycle scan by scan: scan ``sequence_id`` shows scene
``(sequence_id - 1) mod len(scenes)``. With each scan's first Trigger the node publishes that scene's ground
truth for the scan monitor. Run it as ``python -m dptpu.nodes.sim --ros-args -p source:=raycast -p size:=160x120``
or from a launch file (``launch/sim_rig.yaml``). Design: ``docs/scanner.md``.

Topics (defaults; remappable)

================================ ================= ===== ========================================================
topic                            type              dir   notes
================================ ================= ===== ========================================================
``/projector/trigger``           Trigger           in    subscribed once ``/camera/image_raw`` has
                                                         ``min_subscribers`` subscriptions (the projector's own
                                                         scans wait for a trigger subscriber: none is lost)
``/projector/trigger_bursts``    TriggerBurst      in    with ``trigger_bursts``, instead of ``/projector/trigger``:
                                                         an entry's Triggers in one message (the projector's
                                                         ``trigger_bursts:=true``)
``/projector/pattern_sequence``  PatternSequence   in    transient local: checked against the source's sequences
``/camera/image_raw``            FringeFrame       out   the frame + its Trigger; stamp = the Trigger's stamp (with
                                                         ``frame_bursts``: only while it has subscribers)
``/camera/frame_bursts``         FringeBurst       out   with ``frame_bursts``: an entry's frames in one message,
                                                         published with its last frame (:mod:`dptpu.nodes.frame_bursts`)
``/camera/camera_info``          CameraInfo        out   transient local, depth 1: the twin rig's camera
``/sim/ground_truth``            AbsolutePhase     out   per scan, before its frames: true ``Psi`` of the highest
                                                         frequency (Eq. (3)), true fringe order ``floor(f x_p/W)``
                                                         (-1 invalid), ``valid`` = lit by the projector,
                                                         ``reliability`` 1, ``method`` = ``ground_truth:<scene>``
``/sim/ground_truth_depth``      Image (32FC1)     out   per scan: true depth along the camera z axis, metres, NaN
                                                         where no surface; same stamp as its ``/sim/ground_truth``
``/scanner/status``              ScanStatus        out   ERROR ``failed`` once per scan whose Trigger asked for a
                                                         frame the source lacks
================================ ================= ===== ========================================================

Parameters

=================== ============================ =====================================================================
name                default                      meaning
=================== ============================ =====================================================================
``source``          ``"shipped"``                ``shipped`` (``sim/shipped``; live raycast renders of
                                                 ``scenes`` while none are shipped), ``raycast``, or a folder of
                                                 ``dptpu-capture/1`` captures with ``gt.npz``
``rig``             ``"nominal"``                raycast: rig file or ``nominal`` (:func:`dptpu.sim.rig.load_twin_rig`);
                                                 its ``effects`` are rendered
``size``            ``"640x480"``                raycast: camera size ``WIDTHxHEIGHT`` (the rig's ``K`` is rescaled)
``scenes``          ``"random:1,sphere,...``     raycast: built-in names, ``random:SEED`` or scene files, in scan order
``sequence``        ``"96x12,1x12"``             raycast: ``frequency x steps`` entries rendered (the projector's),
                                                 and ``white`` / ``black`` reference frames when named
``fringe_axis``     ``"x"``                      raycast: fringe axis of the rendered patterns
``shift_sign``      -1                           raycast: phase-step sign (-1: the paper's Eq. (1))
``seed``            0                            raycast: noise seed of the first scene (scene i: seed + i)
``bit_depth``       8                            raycast: 8 (mono8) or 16 (mono16)
``frame_rate_hz``   0.0                          at most this many frames per second (a camera's limit); 0 = each frame
                                                 at once, as fast as possible
``drop_frames``     ``""``                       ``SEQUENCE_ID/PATTERN_INDEX,...``: frames not published (tests: an
                                                 incomplete scan)
``min_subscribers`` 1                            subscriptions of ``/camera/image_raw`` (with ``frame_bursts``:
                                                 of ``/camera/frame_bursts``) before Triggers are taken
``frame_bursts``    false                        publish each entry's frames as one FringeBurst (fewer messages a
                                                 scan; the phase node needs ``frame_bursts:=true`` too)
``trigger_bursts``  false                        take the projector's Triggers as TriggerBursts (its
                                                 ``trigger_bursts:=true``) instead of one by one
``ground_truth``    true                         publish ``/sim/ground_truth`` and ``/sim/ground_truth_depth``
``frame_id``        ``"scanner_optical_frame"``  ``header.frame_id`` of frames, CameraInfo and ground truth
=================== ============================ =====================================================================

``frame_rate_hz``, ``drop_frames``, ``min_subscribers``, ``ground_truth`` and ``frame_id`` apply at run time
(``dptpu param set``), checked as at start-up; the others make the renders and are read-only.
"""
from __future__ import annotations

import math
import time
from collections import OrderedDict, deque

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.graph.known_publishers import SOLE_PUBLISHER
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, frame_id
from dptpu.graph.subscription import Subscription
from dptpu.graph.timer import Timer
from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    FringeBurst,
    FringeFrame,
    Header,
    Image,
    PatternSequence,
    ScanStatus,
    Trigger,
    TriggerBurst,
)
from dptpu.messages.scanner import REFERENCE_KINDS
from dptpu.nodes.frame_bursts import Burst, FrameBursts, burst_message, loaned_buffer
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import DEFAULT_FRAME_ID, LATCHED_QOS, STATUS_QOS, ScanFailures, fails_the_scan, scan_status
from dptpu.sim.rig import load_twin_rig

from .source import DEFAULT_SCENES, SimScene, SimSource, load_source

__all__ = ["SimNode", "main", "parse_drop_frames"]

_TWO_PI = 2.0 * np.pi
_SCANS_REMEMBERED = 64


def _drop_frames_problem(text: str) -> None:
    """A check of ``drop_frames``: :func:`parse_drop_frames`'s ValueError is the reason."""
    parse_drop_frames(text)


def parse_drop_frames(text: str) -> set[tuple[int, int]]:
    """``"3/5,7/0"`` -> ``{(3, 5), (7, 0)}`` (sequence id, pattern index); ValueError naming the parameter.

    (Not ``3:5``: YAML, which types ``-p`` values, reads that as the base-60 integer 185.)
    """
    out = set()
    for token in str(text).split(","):
        token = token.strip()
        if not token:
            continue
        scan, sep, pattern = token.partition("/")
        if not sep or not scan.isdigit() or not pattern.isdigit():
            raise ValueError(f"parameter drop_frames: {token!r} must be SEQUENCE_ID/PATTERN_INDEX (e.g. 3/5)")
        out.add((int(scan), int(pattern)))
    return out


class _GroundTruth:
    """The ``/sim/ground_truth`` arrays of one scene, made once."""

    def __init__(self, scene: SimScene, frequency: float, extent_px: int):
        ratio = frequency / extent_px
        with np.errstate(invalid="ignore"):
            self.absolute_phase = (_TWO_PI * ratio * scene.projector_coord).astype(np.float32)  # (H, W) rad
            order = np.floor(ratio * scene.projector_coord.astype(np.float64))
        self.fringe_order = np.where(scene.valid, order, -1).astype(np.int32)  # (H, W)
        self.reliability = np.ones(scene.valid.shape, np.float32)
        self.depth_m = np.ascontiguousarray(scene.depth_m)


class SimNode(Node):
    """Trigger -> the twin's FringeFrame of that pattern (see the module docstring).

    Counters: ``frames_published``, ``frames_dropped`` (by ``drop_frames``), ``triggers_unknown`` (no such frame),
    ``bursts_published`` (with ``frame_bursts``).
    """

    def __init__(self, node_name: str = "sim", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        rendered = "the renders are made at start-up; restart the node to change it"
        source = rules.read_only("source", "shipped", description=rendered)
        rig = rules.read_only("rig", "nominal", description=rendered)
        size = rules.read_only("size", "640x480", description=rendered)
        scenes = rules.read_only("scenes", DEFAULT_SCENES, description=rendered)
        sequence = rules.read_only("sequence", "96x12,1x12", description=rendered)
        fringe_axis = rules.read_only("fringe_axis", "x", description=rendered)
        shift_sign = rules.read_only("shift_sign", -1, description=rendered)
        seed = rules.read_only("seed", 0, description=rendered)
        bit_depth = rules.read_only("bit_depth", 8, description=rendered)
        self.frame_bursts = rules.read_only("frame_bursts", False, description="sets the frames' publisher up")
        self.trigger_bursts = rules.read_only("trigger_bursts", False,
                                              description="sets the Triggers' subscription up")
        self.pace_timer: Timer | None = None
        self.frame_rate_hz = float(rules.settable("frame_rate_hz", 0.0, check=at_least(0.0),
                                                  apply=self._set_frame_rate))
        self.drop_frames = parse_drop_frames(rules.settable("drop_frames", "", check=_drop_frames_problem,
                                                            apply=self._set_drop_frames))
        self.min_subscribers = rules.settable("min_subscribers", 1, check=at_least(0))
        self.publish_truth = rules.settable("ground_truth", True,
                                            apply=lambda value: setattr(self, "publish_truth", value))
        self.frame_id = rules.settable("frame_id", DEFAULT_FRAME_ID, check=frame_id, apply=self._set_frame_id)
        if bit_depth not in (8, 16):
            raise ValueError(f"parameter bit_depth must be 8 or 16; got {bit_depth}")
        # the camera is announced as soon as it is known, before the raycast renders the scenes: the cloud node
        # builds its triangulation tables meanwhile, not while the first scans arrive (docs/scanner.md)
        self.info_pub = self.create_publisher(CameraInfo, "/camera/camera_info", LATCHED_QOS)
        self._info_rig: Rig | None = None  # the rig of the CameraInfo published last (None: none yet)
        self.source: SimSource = load_source(source, rig=rig, size=size, scenes=scenes, sequence=sequence,
                                             fringe_axis=fringe_axis, shift_sign=shift_sign, seed=seed,
                                             bit_depth=bit_depth, log=self.get_logger().info,
                                             on_rig=self._publish_camera_info)
        self.get_logger().info(self.source.note)
        if self.source.kind != "raycast":
            self._check_rig(rig, size)
        extent_px = self.source.rig.projector.size[0 if self.source.fringe_axis == "x" else 1]
        self.truth_frequency = max(f for f, _ in self.source.sequences)
        self._truths = [_GroundTruth(scene, self.truth_frequency, extent_px) if scene.has_truth else None
                        for scene in self.source.scenes]  # None: a capture of a real rig (no gt.npz)
        self._truthless_said: set[str] = set()  # scenes without ground truth already named in the log
        self.frames_published = 0
        self.frames_dropped = 0
        self.triggers_unknown = 0
        self._scans_seen: OrderedDict[int, bool] = OrderedDict()  # sequence_id -> failed already reported
        self._queue: deque = deque()  # (trigger, due monotonic s) when paced
        self._next_due_s = 0.0

        self.image_pub = self.create_publisher(FringeFrame, "/camera/image_raw", 100)
        self.burst_pub = self.create_publisher(FringeBurst, "/camera/frame_bursts", 10) if self.frame_bursts else None
        self.bursts = FrameBursts(lambda shape, dtype: loaned_buffer(self.burst_pub, shape, dtype)) \
            if self.frame_bursts else None
        self.bursts_published = 0
        self.truth_pub = self.create_publisher(AbsolutePhase, "/sim/ground_truth", 10)
        self.truth_depth_pub = self.create_publisher(Image, "/sim/ground_truth_depth", 10)
        self.status_pub = self.create_publisher(ScanStatus, "/scanner/status", STATUS_QOS)
        self.scan_failures = ScanFailures(self, self.status_pub)  # an exception in a scan fails that scan
        self.sequence_sub = self.create_subscription(PatternSequence, "/projector/pattern_sequence",
                                                     self.on_pattern_sequence, LATCHED_QOS,
                                                     publishers=SOLE_PUBLISHER)  # the projector's only
        self.trigger_sub: Subscription | None = None  # created by on_wait_timer once the frames have subscribers
        if self._info_rig is None:  # captures and shipped renders: their rig comes with the frames
            self._publish_camera_info(self.source.rig)
        self.wait_timer = self.create_timer(0.05, self.on_wait_timer)
        if self.bursts is not None:
            self.burst_timer = self.create_timer(0.1, self.on_burst_timer)
        self.triggers_received = 0
        self._checks_without_burst_publisher = 0  # trigger_bursts: checks that found only single Triggers
        self.trigger_topic_timer = self.create_timer(1.0, self.on_trigger_topic_timer) if self.trigger_bursts \
            else None
        self._set_frame_rate(self.frame_rate_hz)
        width, height = self.source.size
        self.get_logger().info(f"{len(self.source.scenes)} scene(s) at {width}x{height}, sequences "
                               f"{self.source.describe_sequences()}; waiting for {self.min_subscribers} subscriber(s) "
                               f"of {' or '.join(p.topic_name for p in self._frame_publishers())}")

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_wait_timer(self) -> None:
        """Take Triggers once the frames have ``min_subscribers`` subscriptions (of the bursts and the single frames
        together: with ``frame_bursts`` a phase node that takes single frames is served them)."""
        if sum(p.get_subscription_count() for p in self._frame_publishers()) < self.min_subscribers:
            return
        self.wait_timer.cancel()
        if self.trigger_bursts:
            self.trigger_sub = self.create_subscription(TriggerBurst, "/projector/trigger_bursts",
                                                        self.on_trigger_burst, 20, publishers=SOLE_PUBLISHER)
        else:
            self.trigger_sub = self.create_subscription(Trigger, "/projector/trigger", self.on_trigger, 200,
                                                        publishers=SOLE_PUBLISHER)  # a stranger's Triggers: refused
        self.get_logger().info("frames have subscribers: taking Triggers")

    def on_pattern_sequence(self, msg: PatternSequence) -> None:
        """Warn when the projector's sequence has entries the source cannot show."""
        missing = [f"{e.frequency:g}x{e.steps}" for e in msg.entries
                   if not e.is_reference and not self.source.serves(e.frequency, e.steps)]
        missing += [e.kind for e in msg.entries if e.is_reference and e.kind not in self.source.references]
        if missing:
            self.get_logger().warning(f"the projector's sequence has {', '.join(missing)}, which the source lacks "
                                      f"({self.source.describe_sequences()}): those Triggers get no frame")

    def on_trigger(self, trigger: Trigger) -> None:
        """A pattern is on screen: publish its frame now, or when the frame rate allows."""
        self.triggers_received += 1
        if self.frame_rate_hz <= 0:
            self._serve(trigger)
            return
        now_s = time.monotonic()
        self._next_due_s = max(now_s, self._next_due_s + 1.0 / self.frame_rate_hz)
        self._queue.append((trigger, self._next_due_s))
        self.on_pace_timer()

    def on_burst_timer(self) -> None:
        """Publish a burst whose next frame is late (a lost Trigger, or one refused)."""
        assert self.bursts is not None
        for burst in self.bursts.due(time.monotonic()):
            self._publish_burst(burst)

    def on_trigger_topic_timer(self) -> None:
        """``trigger_bursts``, once a second until a Trigger comes: say once, naming the publishers, when the
        projector publishes single Triggers but no TriggerBursts (a projector given ``trigger_bursts:=false``: no
        scan would ever get a frame)."""
        assert self.trigger_topic_timer is not None
        if self.triggers_received:
            self.trigger_topic_timer.cancel()
            return
        if self.trigger_sub is None or self.get_publishers_info_by_topic("/projector/trigger_bursts"):
            self._checks_without_burst_publisher = 0
            return
        singles = sorted({info.node for info in self.get_publishers_info_by_topic("/projector/trigger")})
        self._checks_without_burst_publisher = self._checks_without_burst_publisher + 1 if singles else 0
        if self._checks_without_burst_publisher == 2:  # twice in a row: not an announcement still on its way
            self.get_logger().warning(
                f"no Trigger can come: nothing publishes /projector/trigger_bursts, where this node takes "
                f"TriggerBursts (trigger_bursts:=true), while {', '.join(singles)} publish(es) single Triggers on "
                f"/projector/trigger; give this node trigger_bursts:=false, or the projector trigger_bursts:=true")

    def on_trigger_burst(self, burst: TriggerBurst) -> None:
        """An entry's patterns were on screen: each Trigger as :meth:`on_trigger` takes it, in order."""
        for trigger in burst.triggers:
            self.on_trigger(trigger)

    def on_pace_timer(self) -> None:
        """Paced mode: publish the frames that are due."""
        now_s = time.monotonic()
        while self._queue and self._queue[0][1] <= now_s:
            self._serve(self._queue.popleft()[0])

    # -- helpers ---------------------------------------------------------------------------------------------

    def _set_frame_id(self, value: str) -> None:
        """``param set /sim frame_id``: the next frames carry it, and the latched CameraInfo is published again with
        it (a late subscriber would otherwise get the old frame)."""
        self.frame_id = value
        if self._info_rig is not None:
            self._publish_camera_info(self._info_rig)

    def _set_drop_frames(self, text: str) -> None:
        self.drop_frames = parse_drop_frames(text)

    def _set_frame_rate(self, frame_rate_hz: float) -> None:
        """Pace the frames at ``frame_rate_hz`` from now on (0: publish each at once, the queued ones now)."""
        self.frame_rate_hz = float(frame_rate_hz)
        if self.pace_timer is not None:
            self.destroy_timer(self.pace_timer)
            self.pace_timer = None
        if self.frame_rate_hz > 0:
            self.pace_timer = self.create_timer(min(0.01, 1.0 / self.frame_rate_hz), self.on_pace_timer)
        else:
            while self._queue:
                self._serve(self._queue.popleft()[0])

    def scene_index(self, sequence_id: int) -> int:
        """Scene shown during scan ``sequence_id`` (scans count from 1)."""
        return (int(sequence_id) - 1) % len(self.source.scenes)

    @fails_the_scan(lambda trigger: trigger.sequence_id)
    def _serve(self, trigger: Trigger) -> None:
        sequence_id = trigger.sequence_id
        index = self.scene_index(sequence_id)
        scene = self.source.scenes[index]
        if trigger.pattern_index == 0 and sequence_id in self._scans_seen:  # a scan starts twice: a new projector
            self.get_logger().info(f"scan {sequence_id} starts again: a new projector numbers its scans anew")
            self._scans_seen.clear()
        if sequence_id not in self._scans_seen:
            self._scans_seen[sequence_id] = False
            while len(self._scans_seen) > _SCANS_REMEMBERED:
                self._scans_seen.popitem(last=False)
            if self.publish_truth:
                self._publish_truth(trigger, index)
        if trigger.kind in REFERENCE_KINDS:  # the projector full on or full off
            reference = scene.references.get(trigger.kind)
            if reference is None:
                self._unknown(trigger, scene)
                return
            stack, step = reference[None], 0
        else:
            refused = _trigger_problem(trigger)
            if refused is not None:
                self._unknown(trigger, scene, refused)
                return
            stack, step = scene.stack(trigger.frequency, trigger.steps), trigger.step
            if stack is None or step >= stack.shape[0]:
                self._unknown(trigger, scene)
                return
        if (sequence_id, trigger.pattern_index) in self.drop_frames:
            self.frames_dropped += 1
            self.get_logger().info(f"dropping pattern {trigger.pattern_index} of scan {sequence_id} (drop_frames)")
            return
        header = Header(stamp=trigger.header.stamp, frame_id=self.frame_id)
        # through shared memory the frame is copied once, as a camera's driver copies it out of its buffer: into a
        # loaned segment (a burst's, or its own), published without a further copy; without it ZeroMQ sends the held
        # frame itself
        image = stack[step]
        if self.bursts is not None:
            for burst in self.bursts.add(trigger, image, header.stamp.to_ns(), time.monotonic()):
                self._publish_burst(burst)
            if not self.image_pub.get_subscription_count():  # single frames too only while someone listens
                self.frames_published += 1
                return
        if self.image_pub.can_loan_messages(image.nbytes):
            (loaned,) = self.image_pub.borrow_loaned_arrays([(image.shape, image.dtype)])
            np.copyto(loaned, image)
            image = loaned
        self.image_pub.publish(FringeFrame(image=Image.from_array(image, header=header), trigger=trigger))
        self.frames_published += 1

    def _frame_publishers(self) -> list:
        """The publishers a phase node may take frames from: the bursts' (with ``frame_bursts``) and the frames'."""
        return [self.image_pub] if self.burst_pub is None else [self.burst_pub, self.image_pub]

    def _publish_burst(self, burst: Burst) -> None:
        assert self.burst_pub is not None
        self.burst_pub.publish(burst_message(burst, self.frame_id))
        self.bursts_published += 1

    def _publish_truth(self, trigger: Trigger, index: int) -> None:
        truth = self._truths[index]
        if truth is None:
            name = self.source.scenes[index].name
            if name not in self._truthless_said:
                self._truthless_said.add(name)
                self.get_logger().warning(f"scene {name} has no ground truth (its capture has no gt.npz): no "
                                          f"/sim/ground_truth for its scans; grade them with ground_truth:=false")
            return
        header = Header(stamp=trigger.header.stamp, frame_id=self.frame_id)
        width, height = self.source.rig.projector.size
        self.truth_pub.publish(AbsolutePhase(
            header=header, sequence_id=trigger.sequence_id, frequency=float(self.truth_frequency),
            fringe_axis=self.source.fringe_axis, projector_width=width, projector_height=height,
            absolute_phase=truth.absolute_phase, fringe_order=truth.fringe_order, valid=self.source.scenes[index].valid,
            reliability=truth.reliability, method=f"ground_truth:{self.source.scenes[index].name}"))
        self.truth_depth_pub.publish(Image.from_array(truth.depth_m, "32FC1", header=header))

    def _unknown(self, trigger: Trigger, scene: SimScene, refused: str | None = None) -> None:
        """Log (throttled) and report once per scan a Trigger that gets no frame: one the source lacks, or one
        refused for ``refused`` (:func:`_trigger_problem`)."""
        self.triggers_unknown += 1
        why = refused or f"scene {scene.name} has {self.source.describe_sequences()}"
        reason = (f"sim: no frame for pattern {trigger.pattern_index} of scan {trigger.sequence_id} "
                  f"(f={trigger.frequency:g}, step {trigger.step} of {trigger.steps}); {why}")
        self.get_logger().warning(f"{reason} ({self.triggers_unknown} so far)", throttle_duration_sec=1.0)
        if self._scans_seen.get(trigger.sequence_id):
            return
        self._scans_seen[trigger.sequence_id] = True
        self.status_pub.publish(scan_status(self, trigger.sequence_id, ScanStatus.ERROR, "failed", reason,
                                            frames_expected=trigger.pattern_count, frames_dropped=1))

    def _check_rig(self, rig, size) -> None:
        """Warn when replayed captures were made with another rig than ``rig`` (which the cloud node is given)."""
        try:
            expected = load_twin_rig(rig, size=self.source.size)
        except (ValueError, FileNotFoundError) as exc:
            self.get_logger().warning(f"cannot compare the captures' calibration with parameter rig: {exc}")
            return
        got = self.source.rig
        same = got.projector.size == expected.projector.size and all(
            np.allclose(a, b, rtol=1e-6, atol=1e-6) for a, b in (
                (got.projector.K, expected.projector.K), (got.projector.R, expected.projector.R),
                (got.projector.T, expected.projector.T), (got.camera.R, expected.camera.R),
                (got.camera.T, expected.camera.T), (got.camera.K, expected.camera.K)))
        if not same:
            self.get_logger().warning(f"the captures' calibration differs from parameter rig ({rig}); a cloud node "
                                      "given that rig triangulates them wrongly: give it the captures' "
                                      "calibration.yaml")

    def _publish_camera_info(self, rig: Rig) -> None:
        self.info_pub.publish(self.camera_info(rig))
        self._info_rig = rig

    def camera_info(self, rig=None) -> CameraInfo:
        """The CameraInfo of ``rig``'s camera (default: the source's)."""
        camera = (rig or self.source.rig).camera
        width, height = camera.size
        return CameraInfo.from_intrinsics(camera.K, camera.dist, width, height,
                                          header=Header(stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id))


def main(argv=None) -> int:
    """``python -m dptpu.nodes.sim [--ros-args ...]``: run the node until Ctrl-C or SIGTERM (2: bad parameters)."""
    return run_node("sim", SimNode, argv)


def _trigger_problem(trigger: Trigger) -> str | None:
    """Why a Trigger cannot name a frame (None when it can): ``steps`` 0 ("unknown" on the wire) or a step outside
    ``[0, steps)``, a frequency that is not a finite positive number."""
    if trigger.steps < 1:
        return f"refused: Trigger.steps is {trigger.steps} (unknown); the sim needs N >= 1 to pick the frame"
    if not 0 <= trigger.step < trigger.steps:
        return f"refused: Trigger.step {trigger.step} is outside [0, steps = {trigger.steps})"
    if not (math.isfinite(trigger.frequency) and trigger.frequency > 0):
        return f"refused: Trigger.frequency must be a finite number > 0; got {trigger.frequency!r}"
    return None
