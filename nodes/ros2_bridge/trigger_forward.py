"""A ROS 2 ``std_srvs/srv/Trigger`` service on DDS answered by a graph Trigger service: the bridge's reverse
direction (``/scanner/capture`` -> the projector's ``~/start_scan``, ``/scanner/capture_and_save`` -> the cloud
node's ``~/capture_and_save``).

The DDS side follows ``rmw_cyclonedds_cpp`` (:mod:`.ros2_idl`): requests on ``rq/<service>Request``, replies on
``rr/<service>Reply``, each sample led by the request header (``client_guid``, ``sequence_number``) that the reply
repeats, so the ROS 2 client finds its answer.
"""
from __future__ import annotations

from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from dptpu.graph.interfaces import Trigger as TriggerService

from .ros2_idl import Trigger_Request_, Trigger_Response_, ros_topic_name
from .ros2_qos import ros2_qos

__all__ = ["TriggerForward"]


class TriggerForward:
    """DDS requests of ROS 2 service ``ros_service`` forwarded to the graph service ``graph_service`` of ``node``.

    Parameters
    ----------
    node : Node
        The bridge (it makes the graph client).
    participant : DomainParticipant
        The bridge's DDS participant.
    ros_service, graph_service : str
        ``/scanner/capture`` (DDS, absolute) and ``projector/start_scan`` (the graph's, resolved in the node's
        namespace as rclpy does).
    """

    def __init__(self, node, participant, ros_service: str, graph_service: str):
        qos = ros2_qos("services_default")
        request_topic = Topic(participant, ros_topic_name(ros_service + "Request", prefix="rq"), Trigger_Request_,
                              qos=qos)
        reply_topic = Topic(participant, ros_topic_name(ros_service + "Reply", prefix="rr"), Trigger_Response_,
                            qos=qos)
        self.ros_service = ros_service
        self.reader = DataReader(participant, request_topic, qos=qos)
        self.writer = DataWriter(participant, reply_topic, qos=qos)
        self.client = node.create_client(TriggerService, graph_service)
        self.requests = 0

    def poll(self) -> None:
        """Forward each DDS request waiting; the graph service's answer (or why there is none) is the reply."""
        for request in self.reader.take(N=16):
            if not isinstance(request, Trigger_Request_):
                continue  # an invalid sample (e.g. a disposed instance)
            self.requests += 1
            if not self.client.service_is_ready():
                self._reply(request, False, f"{self.client.srv_name} is not available")
                continue
            future = self.client.call_async(TriggerService.Request())
            future.add_done_callback(lambda done, req=request: self._answered(req, done))

    def _answered(self, request: Trigger_Request_, future) -> None:
        if future.exception() is not None:
            self._reply(request, False, f"{self.client.srv_name} failed: {future.exception()}")
            return
        response = future.result()
        self._reply(request, bool(response.success), response.message)

    def _reply(self, request: Trigger_Request_, success: bool, message: str) -> None:
        self.writer.write(Trigger_Response_(client_guid=request.client_guid, sequence_number=request.sequence_number,
                                            success=success, message=message))
