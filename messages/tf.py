"""``tf2_msgs/msg/TFMessage``: the message of ROS 2's ``/tf`` and ``/tf_static`` topics.

``/tf_static`` is published once, latched (reliable, transient local, depth 1), with every static transform of a
publisher in one message, as tf2_ros' ``StaticTransformBroadcaster`` does.
"""

from __future__ import annotations

from .geometry import TransformStamped
from .schema import Message, message, nested_list

__all__ = ["TFMessage"]


@message("tf2_msgs/msg/TFMessage", version=1)
class TFMessage(Message):
    """Transforms published together, ROS 2 ``tf2_msgs/msg/TFMessage``."""

    transforms: list = nested_list(TransformStamped)
