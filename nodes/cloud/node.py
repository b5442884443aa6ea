"""Cloud node: triangulates each scan's absolute phase into an organized point cloud and a depth image.

The absolute phase gives the projector coordinate ``x_p = Psi * W / (2*pi*f)``; each camera pixel's ray meets
that projector plane (the paper's Eq. (10), both lens distortions corrected; :class:`dptpu.fpp.triangulate.
Triangulator`). Points are moved from the rig's world frame into the camera optical frame with the camera's
``R``, ``T`` (``X_cam = R X_world + T``) and scaled from the rig's units to metres (REP 103).

Topics (defaults; remappable)

=========================== ============= ===== ==================================================================
topic                       type          dir   notes
=========================== ============= ===== ==================================================================
``/scanner/absolute_phase`` AbsolutePhase in    reliable, depth 10
``/scanner/texture``        Image         in    depth 4: 32FC1 texture of the same scan (stamp) becomes
                                                 ``intensity`` (the phase node's)
``/scanner/intensity``      Image         in    depth 4: 32FC1 modulation of the same scan (stamp) becomes
                                                 ``modulation`` (the unwrap node's)
``/camera/camera_info``     CameraInfo    in    transient local, only with ``use_camera_info``
``/scanner/points``         PointCloud2   out   organized H x W; float32 x, y, z (m), intensity (texture, DN),
                                                 modulation (DN), confidence, normal_x/y/z (:mod:`.cloud_fields`)
``/scanner/depth/image``    Image         out   32FC1, z in metres, NaN where invalid
``/scanner/depth/camera_info`` CameraInfo out   the camera's intrinsics with each depth image's header (the ROS
                                                 image_transport sibling)
``/scanner/confidence/image`` Image       out   32FC1, the cloud's ``confidence`` (in [0, 1] for each published
                                                 point, 0 where none), the cloud's stamp
``/scanner/confidence/camera_info`` CameraInfo out as for the depth image
``~/capture_and_save``      Trigger (srv)       the last scan's cloud (PLY/PCD, metres, every field) and frames (a
                                                 capture folder) to ``save_dir`` (:mod:`.capture_service`: its
                                                 parameters ``save_dir``, ``save_format``, ``save_units``,
                                                 ``save_frames`` and topics)
``/scanner/status``         ScanStatus    out   one per scan: ``done`` (OK, WARN) or ``failed``; ``duration_s`` =
                                                 ``header.stamp`` - the scan's stamp (its cloud's), to the ns
``/tf_static``              TFMessage     out   latched (transient local): ``mount_frame`` -> ``frame_id`` (the
                                                 mount transform) -> ``projector_frame`` (from the rig), metres;
                                                 published again when one of them is set
=========================== ============= ===== ==================================================================

Parameters

====================== ========================= ===================================================================
name                   default                   meaning
====================== ========================= ===================================================================
``rig``                "" (required)             a ``dptpu-rig/1`` (or OpenCV rig) file: camera and projector
                                                 calibration
``use_camera_info``    false                     take the camera's K, distortion and size from
                                                 ``/camera/camera_info`` (R, T and the projector still from ``rig``)
``frame_id``           "scanner_optical_frame"   ``header.frame_id`` of the cloud and the depth image
``distortion``         true                      correct both lens distortions (false: the pinhole model)
``ply_dir``            ""                        folder for PLY snapshots through open3d ("" = none)
``ply_every``          0                         write scan 1, 1 + n, 1 + 2n, ... as PLY (0 = none), in metres
``intensity_wait_s``   0.2                       how long a scan may wait for its intensity image (published first,
                                                 but the two topics race); only while an intensity publisher is
                                                 connected
``camera_info_wait_s`` 5.0                       with ``use_camera_info``: how long a scan may wait for the first
                                                 CameraInfo (at most 8 scans wait; a scan that waited in vain fails
                                                 with the reason)
``min_confidence``     0.2                       pixels whose confidence (``AbsolutePhase.reliability``, see
                                                 :mod:`dptpu.fpp.confidence`) is lower get no point; 0 keeps all
``drop_edges``         true                      drop the points at depth edges (:func:`dptpu.fpp.depth_edges.
                                                 edge_points`: flying points between surfaces, points beside a
                                                 depth step, modulation dips at edges, partly shadowed points
                                                 predicted more than 1 mm off, isolated points; the modulation
                                                 and shadow tests need the intensity image)
``max_edge_slope``     4.0                       depth step between neighbours, in pixel footprints ``z / f``, above
                                                 which a point apart from both neighbours along a line is flying
``drop_order_islands`` true                      drop the islands of a wrong fringe order (:func:`dptpu.fpp.
                                                 order_islands.order_islands`: regions whole orders off from the
                                                 surface around them; the modulation test needs the intensity
                                                 image, without it every border pair counts as smooth)
``normals``            true                      the fields normal_x/y/z (surface normals from the organized
                                                 neighbours, after the edge filter; toward the camera)
``normal_window_px``   3                         width of the window whose tangents make a normal (odd; 1 = the
                                                 point's own central differences: less bias on small curved parts,
                                                 more noise; :mod:`dptpu.fpp.organized_normals`)
``mount_frame``        "scanner_mount"           TF parent of the camera optical frame: a robot's flange
                                                 (``tool0``, eye-in-hand) or base (eye-to-hand)
``mount_transform``    [0, 0, 0, 0, 0, 0, 1]     the camera optical frame's pose in ``mount_frame``: ``[x, y, z,
                                                 qx, qy, qz, qw]``, metres (``dptpu calibrate hand-eye`` writes it)
``projector_frame``    "projector_optical_frame" TF frame of the projector (an inverse camera, same axes)
====================== ========================= ===================================================================

Read-only (fixed at start-up, ``param set`` refused): ``rig``, ``use_camera_info``, ``intensity_wait_s``. The others
apply from the next scan (``dptpu param set /cloud frame_id base_link``), checked as at start-up: a bad value is
refused with the reason and the old one stays.

What is dropped is counted: counters ``points_low_confidence``, ``points_flying``, ``points_modulation_dip``,
``points_beside_step``, ``points_shadow_border``, ``points_isolated``, ``points_on_islands`` and the scan's status
reason (level OK).

Fields of the cloud (:mod:`dptpu.nodes.cloud.cloud_fields`): ``x, y, z`` NaN where the pixel is invalid
(``is_dense`` false); ``intensity`` the texture (DN) from ``/scanner/texture``, ``modulation`` the fringe
modulation B of the unwrapped frequency (DN) from ``/scanner/intensity`` (each NaN when the scan's image was not
seen); ``confidence`` ``AbsolutePhase.reliability`` in [0, 1] (the classical rounding margin or the network's
confidence; 0 where there is no point); ``normal_x, normal_y, normal_z``. Run:
``python -m dptpu.nodes.cloud --ros-args -p rig:=calibration.yaml``; design: ``docs/nodes.md``.
"""
from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig, load_rig
from dptpu.fpp.confidence import DEFAULT_MIN_CONFIDENCE
from dptpu.fpp.depth_edges import DEFAULT_MAX_EDGE_ERROR_MM, edge_points
from dptpu.fpp.flying_points import DEFAULT_MAX_SLOPE
from dptpu.fpp.order_islands import order_islands
from dptpu.fpp.organized_normals import DEFAULT_NORMAL_WINDOW_PX, organized_normals
from dptpu.fpp.point_cloud_file import write_point_cloud
from dptpu.fpp.scanner_frames import IDENTITY_MOUNT, mount_pose, scanner_frames
from dptpu.fpp.shadow_border import depth_per_pixel
from dptpu.fpp.triangulate import Triangulator, projector_coordinate
from dptpu.graph.known_publishers import SOLE_PUBLISHER
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, frame_id, greater_than, within
from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    Header,
    Image,
    PointCloud2,
    ScanStatus,
    TFMessage,
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

from .capture_service import CaptureAndSave
from .cloud_fields import FIELDS, SideImages, cloud_fields
from .static_frames import tf_message

__all__ = ["FIELDS", "CloudNode", "camera_points_m", "main"]

_INTENSITIES_KEPT = 4
#: The images a scan waits for (topic short name -> graph topic): the phase node's texture, the unwrap node's
#: modulation.
_SIDE_TOPICS = {"texture": "/scanner/texture", "modulation": "/scanner/intensity"}
#: Scans held at most while the first CameraInfo is awaited (each a full-size AbsolutePhase).
_CAMERA_INFO_WAITING_MAX = 8


def camera_points_m(triangulator: Triangulator, absolute_phase: np.ndarray, frequency: float,
                    extent_px: float) -> np.ndarray:
    """Points of an absolute phase map in the camera optical frame, metres, (H, W, 3) float32.

    Parameters
    ----------
    triangulator : Triangulator
        For the rig and the fringe axis.
    absolute_phase : ndarray (H, W)
        ``Psi`` in radians (Eq. (3) of the paper), NaN where invalid.
    frequency : float
        Periods across the projector extent of ``Psi``.
    extent_px : float
        Projector pixels along the fringe axis (``W`` of ``phi = 2*pi*f*x_p/W``).

    Returns
    -------
    ndarray (H, W, 3) float32
        ``X_cam = (R X_world + T) * scale_to_m``; NaN where the phase is NaN or the point is not in front of
        the camera (``z <= 0``).
    """
    coord = projector_coordinate(absolute_phase, frequency, extent_px)  # (H, W) projector pixels
    return triangulator.camera_points(coord, scale=triangulator.rig.scale_to_m, dtype=np.float32)  # (H, W, 3) m


#: the cloud node's TF frame parameters: three distinct frames on /tf_static
_TF_FRAMES = ("frame_id", "mount_frame", "projector_frame")
#: the parameters /tf_static is made of: the frames and the mount transform
_TF_PARAMETERS = (*_TF_FRAMES, "mount_transform")


class CloudNode(Node):
    """AbsolutePhase -> PointCloud2 + depth Image (see the module docstring).

    Counters: ``scans_published``, ``scans_rejected``, ``ply_written``, ``pixels_nan`` (pixels marked valid whose
    absolute phase was NaN or inf), ``points_low_confidence``, ``points_flying``, ``points_beside_step``,
    ``points_modulation_dip``, ``points_shadow_border``, ``points_isolated`` (dropped; a point may count under
    several edge reasons),
    ``points_on_islands``.
    """

    def __init__(self, node_name: str = "cloud", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        rig_path = rules.read_only("rig", "", description="a dptpu-rig/1 file; restart the node to change it")
        self.use_camera_info = rules.read_only("use_camera_info", False, description="sets the subscriptions up")
        self.frame_id = rules.settable("frame_id", DEFAULT_FRAME_ID, check=_tf_frame(self, rules, "frame_id"),
                                       apply=self._set_frame("frame_id"),
                                       description="header.frame_id of the next clouds and images (and TF's)")
        self.distortion = rules.settable("distortion", True, apply=self._set_distortion)
        self.ply_dir = rules.settable("ply_dir", "")
        self.ply_every = rules.settable("ply_every", 0, check=at_least(0))
        self.intensity_wait_s = rules.read_only("intensity_wait_s", 0.2, description="sets the wait timer's period")
        self.camera_info_wait_s = rules.settable("camera_info_wait_s", 5.0, check=greater_than(0.0))
        self.min_confidence = rules.settable("min_confidence", DEFAULT_MIN_CONFIDENCE, check=within(0.0, 1.0))
        self.drop_edges = rules.settable("drop_edges", True)
        self.max_edge_slope = rules.settable("max_edge_slope", DEFAULT_MAX_SLOPE, check=greater_than(0.0))
        self.drop_order_islands = rules.settable("drop_order_islands", True)
        self.normals = rules.settable("normals", True, description="the fields normal_x/y/z of the next clouds")
        self.normal_window_px = rules.settable("normal_window_px", DEFAULT_NORMAL_WINDOW_PX, check=_odd_window)
        self.mount_frame = rules.settable("mount_frame", "scanner_mount", check=_tf_frame(self, rules, "mount_frame"),
                                          apply=self._set_frame("mount_frame"),
                                          description="TF parent of the camera optical frame (a robot's tool0, ...)")
        self.mount_transform = rules.settable(
            "mount_transform", list(IDENTITY_MOUNT), check=_mount_transform_problem,
            apply=self._set_frame("mount_transform"),
            description="pose of the camera optical frame in mount_frame: [x, y, z, qx, qy, qz, qw], metres")
        self.projector_frame = rules.settable("projector_frame", "projector_optical_frame",
                                              check=_tf_frame(self, rules, "projector_frame"),
                                              apply=self._set_frame("projector_frame"))
        if not rig_path:
            raise ValueError("parameter rig must name a dptpu-rig/1 calibration file (-p rig:=calibration.yaml)")
        if not self.intensity_wait_s > 0:
            raise ValueError(f"parameter intensity_wait_s must be > 0 seconds; got {self.intensity_wait_s}")
        self.rig = load_rig(rig_path)
        if self.ply_dir and self.ply_every:
            import open3d  # noqa: F401 -- a heavy import: loaded now, not in the first scan's callback
        self._triangulators: dict[str, Triangulator] = {}
        if not self.use_camera_info:
            self._triangulator("x")  # the per-rig tables now, not in the first scan
        self._side_images = SideImages(_SIDE_TOPICS, _INTENSITIES_KEPT)  # the scans' texture and modulation images
        self._waiting: dict[int, tuple[AbsolutePhase, float]] = {}  # sequence_id -> (scan, deadline), monotonic s
        self._camera_info_seen = not self.use_camera_info
        self._waiting_for_camera_info: OrderedDict[int, tuple[AbsolutePhase, float]] = OrderedDict()  # same
        self.scans_published = 0
        self.scans_rejected = 0
        self.ply_written = 0
        self.pixels_nan = 0
        self.points_low_confidence = 0
        self.points_flying = 0
        self.points_beside_step = 0
        self.points_modulation_dip = 0
        self.points_isolated = 0
        self.points_shadow_border = 0
        self.points_on_islands = 0

        self.points_publisher = self.create_publisher(PointCloud2, "/scanner/points", 10)
        self.depth_publisher = self.create_publisher(Image, "/scanner/depth/image", 10)
        self.depth_info_publisher = self.create_publisher(CameraInfo, "/scanner/depth/camera_info", 10)
        self.confidence_publisher = self.create_publisher(Image, "/scanner/confidence/image", 10)
        self.confidence_info_publisher = self.create_publisher(CameraInfo, "/scanner/confidence/camera_info", 10)
        self.status_publisher = self.create_publisher(ScanStatus, "/scanner/status", STATUS_QOS)
        self.scan_failures = ScanFailures(self, self.status_publisher)  # an exception in a scan fails that scan
        self.tf_static_publisher = self.create_publisher(TFMessage, "/tf_static", LATCHED_QOS)
        self._publish_static_frames()
        self.add_post_set_parameters_callback(self._republish_static_frames)  # runs after the rules' applies

        self._subscriptions_in = [
            self.create_subscription(AbsolutePhase, "/scanner/absolute_phase", self.on_absolute_phase, 10)]
        self._side_subscriptions = {
            name: self.create_subscription(Image, topic, lambda msg, name=name: self.on_side_image(name, msg),
                                           _INTENSITIES_KEPT)
            for name, topic in _SIDE_TOPICS.items()}
        self._subscriptions_in += self._side_subscriptions.values()
        if self.use_camera_info:
            self._subscriptions_in.append(
                self.create_subscription(CameraInfo, "/camera/camera_info", self.on_camera_info, LATCHED_QOS,
                                         publishers=SOLE_PUBLISHER))  # the camera's (or sim's) only
        self.decode_errors = DecodeErrorCount(*self._subscriptions_in)
        self.capture = CaptureAndSave(self, rules, rig_path)  # ~/capture_and_save: the last scan to disk
        self.wait_timer = self.create_timer(self.intensity_wait_s / 4, self.on_timer)

    # -- TF -------------------------------------------------------------------------------------------------

    def _publish_static_frames(self) -> None:
        """``/tf_static``: mount_frame -> frame_id (the mount transform) -> projector_frame (from the rig)."""
        mount = mount_pose(self.mount_transform, parent=self.mount_frame, child=self.frame_id)
        frames = scanner_frames(self.rig, mount=mount, projector_frame=self.projector_frame)
        self.tf_static_publisher.publish(tf_message(frames, self.get_clock().now().to_msg()))

    def _set_frame(self, name: str):
        """An apply of a TF parameter: set it; ``/tf_static`` goes out again once the whole set is applied
        (:meth:`_republish_static_frames`): an atomic swap of two frames must not publish the half-swapped
        ``A -> A`` in between."""
        def apply(value) -> None:
            setattr(self, name, value)
        return apply

    def _republish_static_frames(self, parameters) -> None:
        """A post-set callback (after the rules' applies): publish ``/tf_static`` if a TF parameter was set."""
        if any(parameter.name in _TF_PARAMETERS for parameter in parameters):
            self._publish_static_frames()

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_camera_info(self, msg: CameraInfo) -> None:
        """Use the camera's intrinsics from now on (R, T from the rig); a K without positive focal lengths (ROS: a K of
        zeros is an uncalibrated camera) is ignored with a warning, so the scans wait for a calibrated one."""
        if not (msg.k[0] > 0 and msg.k[4] > 0):
            self.get_logger().warning(f"ignoring CameraInfo: its focal lengths fx={msg.k[0]:g}, fy={msg.k[4]:g} are "
                                      f"not positive (an uncalibrated camera); the scans wait for a calibrated one")
            return
        try:
            camera = DeviceModel(K=np.reshape(msg.k, (3, 3)), dist=np.asarray(msg.d)[:5], R=self.rig.camera.R,
                                 T=self.rig.camera.T, size=(msg.width, msg.height))
        except ValueError as exc:
            self.get_logger().warning(f"ignoring CameraInfo: {exc}")
            return
        current = self.rig.camera
        if self._camera_info_seen and camera.size == current.size and np.array_equal(camera.K, current.K) \
                and np.array_equal(camera.dist, current.dist):
            return  # the same camera announced again (e.g. a new frame_id): the tables stand
        self.rig = Rig(camera=camera, projector=self.rig.projector, units=self.rig.units, effects=self.rig.effects)
        self._triangulators.clear()
        self._triangulator("x")  # the per-rig tables now, not in the first scan
        self.get_logger().info(f"camera intrinsics from CameraInfo: {msg.width}x{msg.height}")
        self._camera_info_seen = True
        while self._waiting_for_camera_info:
            self.on_absolute_phase(self._waiting_for_camera_info.popitem(last=False)[1][0])

    def on_side_image(self, name: str, msg: Image) -> None:
        """Keep the last few scans' texture or modulation images (by stamp); triangulate a scan that waited for it
        once its other side images are in too."""
        stamp_ns = self._side_images.add(name, msg)
        for sequence_id, (scan, _) in list(self._waiting.items()):
            if scan.header.stamp.to_ns() == stamp_ns and self._side_images_in(stamp_ns):
                self._triangulate(self._waiting.pop(sequence_id)[0])

    def _side_images_in(self, stamp_ns: int) -> bool:
        """Every side topic with a publisher delivered the image of ``stamp_ns``."""
        return all(self._side_images.has(name, stamp_ns) or subscription.get_publisher_count() == 0
                   for name, subscription in self._side_subscriptions.items())

    def on_absolute_phase(self, msg: AbsolutePhase) -> None:
        """Triangulate one scan now, or once its intensity image arrived (at most ``intensity_wait_s`` later); with
        ``use_camera_info``, not before the first CameraInfo (at most ``camera_info_wait_s``)."""
        if not self._camera_info_seen:
            self._waiting_for_camera_info[msg.sequence_id] = (msg, time.monotonic() + self.camera_info_wait_s)
            while len(self._waiting_for_camera_info) > _CAMERA_INFO_WAITING_MAX:
                self._fail_waiting(self._waiting_for_camera_info.popitem(last=False)[1][0],
                                   f"more than {_CAMERA_INFO_WAITING_MAX} scans waiting for the first CameraInfo")
            return
        if self._side_images_in(msg.header.stamp.to_ns()):
            self._triangulate(msg)
        else:
            self._waiting[msg.sequence_id] = (msg, time.monotonic() + self.intensity_wait_s)

    def on_timer(self) -> None:
        """Triangulate the scans whose texture or modulation image did not come in time (that field NaN)."""
        now_s = time.monotonic()
        for sequence_id in [i for i, (_, deadline) in self._waiting.items() if deadline <= now_s]:
            self._triangulate(self._waiting.pop(sequence_id)[0])
        for sequence_id in [i for i, (_, deadline) in self._waiting_for_camera_info.items() if deadline <= now_s]:
            self._fail_waiting(self._waiting_for_camera_info.pop(sequence_id)[0],
                               f"no CameraInfo on /camera/camera_info within {self.camera_info_wait_s:g} s")

    def _fail_waiting(self, msg: AbsolutePhase, why: str) -> None:
        """Report a scan that could not be triangulated while it waited (logged, a failed ScanStatus)."""
        self.scans_rejected += 1
        reason = f"cannot triangulate scan {msg.sequence_id}: {why}"
        self.get_logger().warning(reason)
        self._status(msg, ScanStatus.ERROR, "failed", reason)

    @fails_the_scan(lambda msg: msg.sequence_id)
    def _triangulate(self, msg: AbsolutePhase) -> None:
        """Triangulate one scan; publish its cloud, depth and confidence images (each with its camera_info) and
        status.

        x, y, z are written as three contiguous planes (the triangulation's output, a planar view), the normals as
        three more, then all are interleaved with the texture, modulation and confidence into one fresh (H, W, 9)
        float32 cloud by one ``cv2.merge`` pass, which is published without a copy; the depth image is the z plane
        itself (no copy).
        """
        try:
            coord, nan_pixels, low_confidence = self._projector_coordinate(msg)
            triangulator = self._triangulator(msg.fringe_axis)
            planes = np.empty((3, *coord.shape), dtype=np.float32)  # (3, H, W): x, y, z planes
            triangulator.camera_points(coord, scale=triangulator.rig.scale_to_m, dtype=np.float32,
                                       out=planes.transpose(1, 2, 0))  # metres, NaN where invalid or behind
        except ValueError as exc:
            self.scans_rejected += 1
            reason = f"cannot triangulate scan {msg.sequence_id}: {exc}"
            self.get_logger().warning(reason)
            self._status(msg, ScanStatus.ERROR, "failed", reason)
            return
        header = Header(stamp=msg.header.stamp, frame_id=self.frame_id)
        stamp_ns, shape = msg.header.stamp.to_ns(), coord.shape
        texture = self._side_images.take("texture", stamp_ns, shape)  # (H, W) float32 DN, or None
        modulation = self._side_images.take("modulation", stamp_ns, shape)
        edge_counts = self._drop_edges(planes, modulation, triangulator, coord, msg.valid)
        on_islands = self._drop_islands(planes, msg.absolute_phase, np.isfinite(coord), modulation)
        confidence = np.where(np.isfinite(planes[2]), msg.reliability, np.float32(0.0)).astype(np.float32, copy=False)
        channels = [planes[0], planes[1], planes[2], _or_nan(texture, shape), _or_nan(modulation, shape), confidence]
        if self.normals:
            normals = np.empty((3, *shape), dtype=np.float32)  # (3, H, W) planes
            organized_normals(planes.transpose(1, 2, 0), window_px=self.normal_window_px,
                              out=normals.transpose(1, 2, 0))
            channels += list(normals)
        fields = cloud_fields(self.normals)
        # (H, W, 9) float32 (6 without normals) filled in place in a loaned shared-memory segment, published without
        # a copy (plain memory where there is no shared memory)
        (cloud,) = self.points_publisher.borrow_loaned_arrays([((*shape, len(channels)), np.float32)])
        try:
            cv2.merge(channels, dst=cloud)  # one interleaving pass
            cloud_msg = PointCloud2.from_array(cloud, fields, header=header, is_dense=False)
        except BaseException:
            self.points_publisher.return_loaned_arrays([cloud])
            raise
        self.points_publisher.publish(cloud_msg)
        # the loaned segment is rewritten once the subscribers are done with it: ~/capture_and_save keeps what the
        # cloud is made of (this scan's own planes; copies of the texture and modulation, views of received
        # messages whose segments go back too) and makes it again when asked
        kept = [*channels[:3], channels[3].copy(), channels[4].copy(), *channels[5:]]
        self.capture.keep(msg.sequence_id, lambda: PointCloud2.from_array(cv2.merge(kept), fields, header=header,
                                                                          is_dense=False), msg.fringe_axis)
        depth_m = planes[2]  # (H, W) metres
        camera_info = self._camera_info(header)
        self.depth_publisher.publish(Image.from_array(depth_m, "32FC1", header=header))
        self.depth_info_publisher.publish(camera_info)
        self.confidence_publisher.publish(Image.from_array(confidence, "32FC1", header=header))
        self.confidence_info_publisher.publish(camera_info)
        self.scans_published += 1
        valid_points = int(np.count_nonzero(np.isfinite(depth_m)))
        notes = []  # what was dropped, counted: not a warning
        if low_confidence:
            self.points_low_confidence += low_confidence
            notes.append(f"{low_confidence} pixels below min_confidence {self.min_confidence:g} dropped")
        if edge_counts["total"]:
            notes.append(f"{edge_counts['total']} points at depth edges dropped ({edge_counts['flying']} flying, "
                         f"{edge_counts['beside_step']} beside a step, {edge_counts['modulation_dip']} modulation "
                         f"dips, {edge_counts['shadow_border']} partly shadowed, {edge_counts['isolated']} isolated)")
        if on_islands:
            notes.append(f"{on_islands} points on islands of a wrong fringe order dropped")
        reasons = []
        if nan_pixels:
            self.pixels_nan += nan_pixels
            reasons.append(f"{nan_pixels} pixels marked valid had a non-finite absolute phase; treated as invalid")
        if texture is None:
            reasons.append(f"no texture image of scan {msg.sequence_id} seen: intensity NaN")
        if modulation is None:
            reasons.append(f"no modulation image of scan {msg.sequence_id} seen: modulation NaN")
        if self.ply_dir and self.ply_every and (self.scans_published - 1) % self.ply_every == 0:
            reasons += self._snapshot(msg.sequence_id, cloud[..., :3], cloud[..., 3])
        if reasons:
            self.get_logger().warning(f"scan {msg.sequence_id}: {'; '.join(reasons)}", throttle_duration_sec=1.0)
        self._status(msg, ScanStatus.WARN if reasons else ScanStatus.OK, "done", "; ".join(reasons + notes),
                     valid_pixels=valid_points, total_pixels=int(depth_m.size))

    # -- helpers ---------------------------------------------------------------------------------------------

    def _set_distortion(self, distortion: bool) -> None:
        """Apply ``distortion`` from the next scan: the triangulation tables are made again."""
        self.distortion = distortion
        self._triangulators.clear()
        if self._camera_info_seen:
            self._triangulator("x")

    def _drop_edges(self, planes: np.ndarray, modulation: np.ndarray | None, triangulator: Triangulator,
                    coord: np.ndarray, lit: np.ndarray) -> dict[str, int]:
        """Blank (NaN) the points at depth edges in ``planes`` (3, H, W), count them by reason (counters too).

        ``coord``: the scan's projector coordinate (NaN where no point); ``lit``: the pixels with a phase (the
        message's ``valid``): with the modulation image, the partly shadowed points are judged by their predicted
        depth error (:func:`dptpu.fpp.shadow_border.depth_per_pixel`, one more triangulation of those pixels only).
        """
        if not self.drop_edges:
            return {"flying": 0, "beside_step": 0, "modulation_dip": 0, "shadow_border": 0, "isolated": 0,
                    "total": 0}
        K = triangulator.rig.camera.K
        scale = triangulator.rig.scale_to_m
        per_px: Callable[[np.ndarray], np.ndarray] | None = None
        axis = "x" if triangulator.axis == 0 else "y"
        if modulation is not None:
            def depth_at(projector_x: np.ndarray, pixels: np.ndarray) -> np.ndarray:  # the few pixels asked for
                return triangulator.camera_points(projector_x, scale=scale, dtype=np.float32, pixels=pixels)[:, 2]

            def depth_per_px(where: np.ndarray) -> np.ndarray:  # the second triangulation, where edge_points asks
                return depth_per_pixel(coord, depth_at, axis, depth=planes[2], where=where)

            per_px = depth_per_px
        edges = edge_points(planes[2], 0.5 * float(K[0, 0] + K[1, 1]), modulation, lit=lit, depth_per_px=per_px,
                            max_edge_error=DEFAULT_MAX_EDGE_ERROR_MM * 1e-3, axis=axis,
                            max_slope=self.max_edge_slope)
        counts = edges.counts(np.isfinite(planes[2]))
        _blank(planes, edges.dropped)
        self.points_flying += counts["flying"]
        self.points_beside_step += counts["beside_step"]
        self.points_modulation_dip += counts["modulation_dip"]
        self.points_shadow_border += counts["shadow_border"]
        self.points_isolated += counts["isolated"]
        return counts

    def _drop_islands(self, planes: np.ndarray, absolute_phase: np.ndarray, valid: np.ndarray,
                      modulation: np.ndarray | None) -> int:
        """Blank (NaN) the points in ``planes`` (3, H, W) on islands of a wrong fringe order, found among the
        ``valid`` pixels (those with an order, before the edge filter); how many (counter too)."""
        if not self.drop_order_islands:
            return 0
        b = np.ones(valid.shape, np.float32) if modulation is None else modulation
        island = order_islands(absolute_phase, b, valid).islands
        np.logical_and(island, np.isfinite(planes[2]), out=island)
        _blank(planes, island)
        count = int(np.count_nonzero(island))
        self.points_on_islands += count
        return count

    def _triangulator(self, axis: str) -> Triangulator:
        """The rig's triangulation tables for ``axis`` (rays, projector distortion), made once per rig, and one
        triangulation of the projector's middle column: the first scan's one-time costs (the camera-frame rays of
        ``camera_points``; docs/benchmarks.md) are paid here, not in that scan's latency."""
        if axis not in self._triangulators:
            triangulator = Triangulator(self.rig, axis=axis, distortion=self.distortion)
            middle_px = 0.5 * self.rig.projector.size[0 if axis == "x" else 1]
            triangulator.camera_points(np.full(triangulator.shape, middle_px), scale=self.rig.scale_to_m,
                                       dtype=np.float32)
            self._triangulators[axis] = triangulator
        return self._triangulators[axis]

    def _projector_coordinate(self, msg: AbsolutePhase) -> tuple[np.ndarray, int, int]:
        """Projector coordinate (H, W) float64 of the scan, NaN where invalid, not finite or below
        ``min_confidence``; how many pixels marked valid were not finite, and how many finite ones fell below
        ``min_confidence``; ValueError when the scan does not fit the rig."""
        width, height = self.rig.camera.size
        phase = msg.absolute_phase
        if phase.shape != (height, width):
            raise ValueError(f"absolute_phase is {phase.shape[1]}x{phase.shape[0]} pixels; "
                             f"the rig's camera is {width}x{height}")
        coord = projector_coordinate(phase, msg.frequency, self._extent_px(msg))  # (H, W) float64 projector pixels
        mask = np.isfinite(coord)
        np.logical_and(mask, msg.valid, out=mask)  # (H, W) usable pixels
        usable = int(np.count_nonzero(mask))
        nan_pixels = int(np.count_nonzero(msg.valid)) - usable
        low_confidence = 0
        if self.min_confidence > 0:
            if msg.reliability.shape != mask.shape:
                raise ValueError(f"reliability is {msg.reliability.shape[1]}x{msg.reliability.shape[0]} pixels; "
                                 f"the absolute phase is {width}x{height}")
            np.logical_and(mask, msg.reliability >= self.min_confidence, out=mask)
            low_confidence = usable - int(np.count_nonzero(mask))
        np.logical_not(mask, out=mask)  # (H, W) pixels to blank
        np.copyto(coord, np.nan, where=mask)
        return coord, nan_pixels, low_confidence

    def _extent_px(self, msg: AbsolutePhase) -> int:
        """Projector pixels along the fringe axis: the rig's; ValueError when the message says otherwise."""
        rig_size = tuple(self.rig.projector.size)
        if msg.projector_width and msg.projector_height and (msg.projector_width, msg.projector_height) != rig_size:
            raise ValueError(f"the scan's projector is {msg.projector_width}x{msg.projector_height}; the rig's is "
                             f"{rig_size[0]}x{rig_size[1]}")
        return rig_size[0] if msg.fringe_axis == "x" else rig_size[1]

    def _camera_info(self, header: Header) -> CameraInfo:
        """The camera's intrinsics (the rig's, or the CameraInfo's with ``use_camera_info``) with ``header``: the
        sibling camera_info of the depth and confidence images."""
        camera = self.rig.camera
        return CameraInfo.from_intrinsics(camera.K, camera.dist, camera.size[0], camera.size[1], header=header)

    def _snapshot(self, sequence_id: int, points: np.ndarray, intensity: np.ndarray) -> list[str]:
        path = Path(self.ply_dir) / f"scan_{sequence_id:08d}.ply"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            count = write_point_cloud(path, points, unit="m", intensity=intensity)
        except (OSError, ImportError, RuntimeError, ValueError) as exc:
            self.get_logger().warning(f"PLY snapshot {path} failed: {exc}")
            return [f"PLY snapshot failed: {exc}"]
        self.ply_written += 1
        self.get_logger().info(f"wrote {path} ({count} points)")
        return []

    def _status(self, msg, level, state, reason, **counts) -> None:
        now = self.get_clock().now()
        self.status_publisher.publish(scan_status(
            self, msg.sequence_id, level, state, reason, stamp=now.to_msg(),
            decode_errors=self.decode_errors.since_last_report(),
            duration_s=max(0.0, (now.nanoseconds - msg.header.stamp.to_ns()) * 1e-9), **counts))


def main(argv=None) -> int:
    """``python -m dptpu.nodes.cloud --ros-args -p rig:=FILE``: run the node until Ctrl-C or SIGTERM."""
    return run_node("cloud", CloudNode, argv)


def _tf_frame(node: Node, rules: ParameterRules, name: str):
    """The check of the TF frame parameter ``name``: a valid frame id, and none of the other two (tf2 refuses a
    frame that is its own parent: ``mount_frame`` = ``frame_id`` would publish ``A -> A``)."""
    def check(value) -> str | None:
        problem = frame_id(value)
        if problem:
            return problem
        for other in _TF_FRAMES:
            if other != name and node.has_parameter(other) and rules.value(other) == value:
                return f"must differ from {other} (a TF frame cannot be its own parent or child); got {value!r}"
        return None
    return check


def _mount_transform_problem(values) -> None:
    """The check of ``mount_transform``: 7 finite numbers with a unit quaternion (ValueError says why not)."""
    mount_pose(values, parent="mount", child="camera")


def _odd_window(value) -> str | None:
    """The check of ``normal_window_px``: an odd number of pixels >= 1."""
    return None if isinstance(value, int) and value >= 1 and value % 2 == 1 else \
        f"must be an odd number of pixels >= 1; got {value!r}"


def _blank(planes: np.ndarray, mask: np.ndarray) -> None:
    """Set the (3, H, W) ``planes`` NaN where the (H, W) ``mask`` is set: a masked copy per plane (numpy's boolean
    index assignment ``planes[:, mask] = nan`` costs ~7 times more at 640x480; docs/benchmarks.md, "Floor kernels,
    session 10")."""
    for plane in planes:
        np.copyto(plane, np.float32(np.nan), where=mask)


def _or_nan(image: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray:
    """``image`` as a contiguous (H, W) float32 plane, or NaN everywhere when the scan's image was not seen."""
    if image is None:
        return np.full(shape, np.nan, dtype=np.float32)
    return np.ascontiguousarray(image, dtype=np.float32)
