"""Geometry messages with ROS 2 ``geometry_msgs`` fields: Vector3, Quaternion, Transform, TransformStamped.

What TF is made of (``tf2_msgs/msg/TFMessage`` is a list of TransformStamped, :mod:`.tf`). The scanner publishes
its static frames with them (the mount, the camera optical frame, the projector; ``docs/ros2.md``).

Convention (tf2's): a TransformStamped with ``header.frame_id`` = parent and ``child_frame_id`` = child holds the
pose of the child frame in the parent frame, i.e. ``X_parent = R(rotation) X_child + translation``; translation
in metres, rotation a unit quaternion ``(x, y, z, w)``, ``w`` the scalar part.
"""

from __future__ import annotations

from .schema import Message, message, nested, scalar
from .std import Header

__all__ = ["Vector3", "Quaternion", "Transform", "TransformStamped"]


@message("geometry_msgs/msg/Vector3", version=1)
class Vector3(Message):
    """A free vector, ROS 2 ``geometry_msgs/msg/Vector3`` (float64 ``x``, ``y``, ``z``)."""

    x: float = scalar("float64")
    y: float = scalar("float64")
    z: float = scalar("float64")


@message("geometry_msgs/msg/Quaternion", version=1)
class Quaternion(Message):
    """A rotation, ROS 2 ``geometry_msgs/msg/Quaternion``: ``x, y, z`` the vector part, ``w`` the scalar part.

    The default is the identity (``w = 1``), as in ROS 2.
    """

    x: float = scalar("float64")
    y: float = scalar("float64")
    z: float = scalar("float64")
    w: float = scalar("float64", 1.0)

    def check_consistency(self) -> None:
        norm2 = self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w
        if abs(norm2 - 1.0) > 1e-6:
            raise ValueError(f"Quaternion must have unit norm; got |q|^2 = {norm2}")


@message("geometry_msgs/msg/Transform", version=1)
class Transform(Message):
    """A rigid transform, ROS 2 ``geometry_msgs/msg/Transform``: ``translation`` (m) then ``rotation``."""

    translation: Vector3 = nested(Vector3)
    rotation: Quaternion = nested(Quaternion)


@message("geometry_msgs/msg/TransformStamped", version=1)
class TransformStamped(Message):
    """The pose of ``child_frame_id`` in ``header.frame_id``, ROS 2 ``geometry_msgs/msg/TransformStamped``.

    Attributes
    ----------
    header : Header
        ``frame_id``: the parent frame; ``stamp``: when the transform holds (any time, for a static one).
    child_frame_id : str
        The child frame.
    transform : Transform
        ``X_parent = R X_child + t`` (see the module's Convention).
    """

    header: Header = nested(Header)
    child_frame_id: str = scalar("string")
    transform: Transform = nested(Transform)
