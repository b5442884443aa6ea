"""ROS 2 bridge: republishes the scanner's topics on DDS the way a ROS 2 driver on ``rmw_cyclonedds_cpp`` does.

Each bridged graph topic ``/name`` becomes the DDS topic ``rt/name`` with ROS 2's type name
(``sensor_msgs::msg::dds_::PointCloud2_``), sensor_msgs' members in order, plain CDR, and ROS 2's QoS, written
through Eclipse Cyclone DDS (``cyclonedds`` on PyPI bundles the C library). A ROS 2 host then sees
``/scanner/points`` in ``ros2 topic list`` and subscribes to it like to any driver; the scanner host needs no
ROS 2. The reverse direction: a ``std_srvs/srv/Trigger`` service (``/scanner/capture``) that starts one scan
through the projector's ``~/start_scan``. ROS side, tests and figures: ``docs/ros2.md``.

Topics and services (defaults; the graph names are parameters)

=========================== ============================= ======= ==========================================
graph                       DDS                           dir     notes
=========================== ============================= ======= ==========================================
``/scanner/points``         ``rt/scanner/points``         out     PointCloud2; ROS 2 default QoS (or sensor data)
``/scanner/depth/image``    ``rt/scanner/depth/image``    out     Image 32FC1; as above
``/scanner/depth/camera_info`` (the same name, ``rt/``)   out     CameraInfo of each depth image; as above
``/scanner/confidence/image``, ``.../camera_info``        out     Image 32FC1 and its CameraInfo; as above
``/diagnostics``            ``rt/diagnostics``            out     diagnostic_msgs DiagnosticArray (the scan
                                                                  monitor's); ROS 2 default QoS
``/camera/camera_info``     ``rt/camera/camera_info``     out     CameraInfo; latched (TRANSIENT_LOCAL, depth 1) on
                                                                  both sides
``/tf_static``              ``rt/tf_static``              out     tf2_msgs TFMessage (the cloud node's frames);
                                                                  latched, as tf2_ros' static broadcaster
``/projector/start_scan``   ``rq/scanner/captureRequest`` in      DDS ``std_srvs/srv/Trigger`` service
(client)                    ``rr/scanner/captureReply``   out     ``/scanner/capture``; the reply is the projector's
``/cloud/capture_and_save`` ``rq/scanner/capture_and_save in/out  DDS ``std_srvs/srv/Trigger`` service
(client)                    Request``, ``...Reply``               ``/scanner/capture_and_save``; the reply is the
                                                                  cloud node's (the files it wrote)
=========================== ============================= ======= ==========================================

Parameters

==================== ========================================= =================================================
name                 default                                   meaning
==================== ========================================= =================================================
``topics``           [/scanner/points, /scanner/depth/image,   graph topics republished under the same ROS name;
                     /scanner/depth/camera_info,               each may carry PointCloud2, Image or CameraInfo
                     /scanner/confidence/image,
                     /scanner/confidence/camera_info,
                     /camera/camera_info, /diagnostics,        (or DiagnosticArray, TFMessage)
                     /tf_static]
``latched_topics``   [/camera/camera_info, /tf_static]         of those, the ones published TRANSIENT_LOCAL
``qos``              "default"                                 ROS 2 profile of the other topics: ``default``
                                                               (RELIABLE, depth 10) or ``sensor_data``
                                                               (BEST_EFFORT, depth 5)
``domain_id``        -1                                        DDS domain; -1: ``ROS_DOMAIN_ID`` or 0
``interface``        ""                                        network interface (``lo``, ``eth0``); "": Cyclone's
                                                               choice or ``CYCLONEDDS_URI``
``peers``            ""                                        comma-separated unicast peers (multicast off)
``capture_service``  "/scanner/capture"                        ROS 2 service name of the capture request ("" = none)
``start_service``    "projector/start_scan"                    graph Trigger service it calls (relative: in the
                                                               bridge's namespace, as the nodes it serves)
``save_service``     "/scanner/capture_and_save"               ROS 2 service name of the save request ("" = none)
``save_target``      "cloud/capture_and_save"                  graph Trigger service it calls (relative, as above)
==================== ========================================= =================================================

Every parameter is read-only (the DDS side is made at start-up; ``param set`` is refused).

Counters: ``bridged`` (per topic), ``malformed``, ``rejected`` (a message of another type than the topic's first),
``capture_requests``. Run: ``python -m dptpu.nodes.ros2_bridge --ros-args -p domain_id:=0 -p interface:=eth0``.
"""
from __future__ import annotations

import os

from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic

from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules
from dptpu.graph.qos import QoSProfile, ReliabilityPolicy
from dptpu.messages import CameraInfo, DecodeError, DiagnosticArray, Image, PointCloud2, TFMessage, decode
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import LATCHED_QOS

from .ros2_idl import dds_type_of, ros_topic_name, to_dds
from .ros2_qos import cyclone_config_xml, ros2_qos
from .trigger_forward import TriggerForward

__all__ = ["Ros2BridgeNode", "DEFAULT_TOPICS", "DEFAULT_TYPES", "main"]

DEFAULT_TOPICS = ["/scanner/points", "/scanner/depth/image", "/scanner/depth/camera_info", "/scanner/confidence/image",
                  "/scanner/confidence/camera_info", "/camera/camera_info", "/diagnostics", "/tf_static"]
#: Of those, the ones kept for late joiners (TRANSIENT_LOCAL, depth 1) on both sides.
DEFAULT_LATCHED = ["/camera/camera_info", "/tf_static"]
#: Types of the default topics: their DDS writers exist from the start, so ROS 2 sees them before the first scan.
DEFAULT_TYPES = {"/scanner/points": PointCloud2, "/scanner/depth/image": Image,
                 "/scanner/depth/camera_info": CameraInfo, "/scanner/confidence/image": Image,
                 "/scanner/confidence/camera_info": CameraInfo, "/camera/camera_info": CameraInfo,
                 "/diagnostics": DiagnosticArray, "/tf_static": TFMessage}
_GRAPH_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)  # connects to any publisher
_REQUEST_POLL_S = 0.02


def _domain_id(value: int) -> int:
    if value >= 0:
        return value
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit():
        raise ValueError(f"ROS_DOMAIN_ID must be a non-negative integer; got {text!r}")
    return int(text)


class Ros2BridgeNode(Node):
    """Graph topics -> DDS ``rt/`` topics; DDS ``/scanner/capture`` -> the projector (see the module docstring)."""

    def __init__(self, node_name: str = "ros2_bridge", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        wiring = "the DDS participant, readers and writers are made at start-up; restart the node to change it"
        topics = list(rules.read_only("topics", DEFAULT_TOPICS, description=wiring))
        latched = set(rules.read_only("latched_topics", DEFAULT_LATCHED, description=wiring))
        self.qos_profile = rules.read_only("qos", "default", description=wiring)
        domain_id = rules.read_only("domain_id", -1, description=wiring)
        interface = rules.read_only("interface", "", description=wiring)
        peers = tuple(p.strip() for p in rules.read_only("peers", "", description=wiring).split(",") if p.strip())
        capture_service = rules.read_only("capture_service", "/scanner/capture", description=wiring)
        start_service = rules.read_only("start_service", "projector/start_scan", description=wiring)
        save_service = rules.read_only("save_service", "/scanner/capture_and_save", description=wiring)
        save_target = rules.read_only("save_target", "cloud/capture_and_save", description=wiring)
        if self.qos_profile not in ("default", "sensor_data"):
            raise ValueError(f"parameter qos must be 'default' or 'sensor_data'; got {self.qos_profile!r}")
        if domain_id > 232:
            raise ValueError(f"parameter domain_id must be -1 (ROS_DOMAIN_ID) or 0..232; got {domain_id}")
        for topic in topics + sorted(latched) + [name for name in (capture_service, save_service) if name]:
            ros_topic_name(topic)  # ValueError naming a bad name
        self.domain_id = _domain_id(domain_id)

        config = cyclone_config_xml(interface, peers)
        self._dds_domain = Domain(self.domain_id, config) if config else None
        self.participant = DomainParticipant(self.domain_id)
        self._latched = latched
        self._writers: dict[str, tuple[type, object]] = {}   # graph topic -> (our message class, DataWriter)
        self.bridged = {topic: 0 for topic in topics}
        self.malformed = 0
        self.rejected = 0
        self.capture_requests = 0
        for topic in topics:
            if topic in DEFAULT_TYPES:
                self._writer_for(topic, DEFAULT_TYPES[topic])

        self._subscriptions_in = [
            self.create_subscription(None, topic, self._forwarder(topic),
                                     LATCHED_QOS if topic in latched else _GRAPH_QOS, raw=True)
            for topic in topics]

        self.capture_service = capture_service
        self.forwards = [TriggerForward(self, self.participant, ros_name, graph_name)
                         for ros_name, graph_name in ((capture_service, start_service), (save_service, save_target))
                         if ros_name]  # the ROS 2 services the bridge answers, each by a graph Trigger service
        if self.forwards:
            self.request_timer = self.create_timer(_REQUEST_POLL_S, self.on_request_timer)

    # -- graph -> DDS ------------------------------------------------------------------------------------------

    def _writer_for(self, topic: str, msg_type: type):
        """The DDS writer of ``topic`` for ``msg_type`` (created on first use); None if the topic has another."""
        if topic in self._writers:
            known_type, writer = self._writers[topic]
            return writer if known_type is msg_type else None
        qos = ros2_qos("latched" if topic in self._latched else self.qos_profile)
        dds_topic = Topic(self.participant, ros_topic_name(topic), dds_type_of(msg_type), qos=qos)
        writer = DataWriter(self.participant, dds_topic, qos=qos)
        self._writers[topic] = (msg_type, writer)
        return writer

    def _forwarder(self, topic: str):
        def forward(frames) -> None:
            self.on_message(topic, frames)
        return forward

    def on_message(self, topic: str, frames) -> None:
        """Decode one graph message of ``topic`` and write it to its DDS topic (no copy of the bulk data)."""
        try:
            _, msg = decode(frames)
        except DecodeError as exc:
            self.malformed += 1
            self.get_logger().warning(f"malformed message on {topic}: {exc}", throttle_duration_sec=1.0)
            return
        try:
            writer = self._writer_for(topic, type(msg))
        except ValueError as exc:
            writer, reason = None, str(exc)
        else:
            reason = f"{topic} is bridged as {self._writers[topic][0].__name__}"
        if writer is None:
            self.rejected += 1
            self.get_logger().warning(f"not bridging a {type(msg).__name__} on {topic}: {reason}",
                                      throttle_duration_sec=5.0)
            return
        writer.write(to_dds(msg))
        self.bridged[topic] += 1

    # -- DDS service requests -> graph ----------------------------------------------------------------------

    def on_request_timer(self) -> None:
        """Forward each DDS capture or save request to its graph service; its answer becomes the DDS reply."""
        for forward in self.forwards:
            forward.poll()
        self.capture_requests = sum(forward.requests for forward in self.forwards
                                    if forward.ros_service == self.capture_service)


def main(argv=None) -> int:
    """``python -m dptpu.nodes.ros2_bridge --ros-args -p domain_id:=N``: run until Ctrl-C or SIGTERM."""
    return run_node("ros2_bridge", Ros2BridgeNode, argv)

