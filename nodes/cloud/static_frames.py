"""The cloud node's ``/tf_static``: the scanner's frames (:mod:`dptpu.fpp.scanner_frames`) as one TFMessage."""
from __future__ import annotations

from collections.abc import Sequence

from dptpu.fpp.scanner_frames import FramePose
from dptpu.messages import Header, Quaternion, TFMessage, Time, Transform, TransformStamped, Vector3

__all__ = ["tf_message"]


def tf_message(frames: Sequence[FramePose], stamp: Time) -> TFMessage:
    """One TFMessage holding every pose of ``frames`` (parent -> child), stamped ``stamp``, as tf2_ros'
    StaticTransformBroadcaster sends its static transforms."""
    transforms = []
    for pose in frames:
        x, y, z, w = (float(v) for v in pose.quaternion_xyzw())
        tx, ty, tz = (float(v) for v in pose.t)
        transforms.append(TransformStamped(
            header=Header(stamp=stamp, frame_id=pose.parent), child_frame_id=pose.child,
            transform=Transform(translation=Vector3(x=tx, y=ty, z=tz), rotation=Quaternion(x=x, y=y, z=z, w=w))))
    return TFMessage(transforms=transforms)
