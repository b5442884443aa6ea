"""Recording and playback of topics as MCAP files (``dptpu record`` / ``dptpu play``).

- :mod:`.mcap_io`: :class:`McapRecordWriter`, :func:`read_mcap`, :func:`describe_mcap`, :func:`verify_mcap`
  (no graph needed).
- :mod:`.mcap_integrity`: the file's CRCs (chunks, data section, summary) checked, the first fault's offset named.
- :mod:`.offered_qos`: rosbag2's ``offered_qos_profiles`` YAML of each channel.
- :mod:`.ros2_cdr`: ROS types <-> CDR dicts (mcap-ros2-support), for ROS 2 bags written elsewhere; every channel this
  package writes is CDR by :mod:`dptpu.messages.cdr`.
- :mod:`.msgpack_records`: the ``dptpu-msgpack`` encoding of the scanner's own types in files of earlier builds
  (read only).
- :mod:`.recorder`, :mod:`.player`: subscribe and write, read and publish (they use the graph runtime).

The file layout is specified in ``docs/recording.md``.
"""

from .mcap_io import (
                      ChannelSummary,
                      McapReadError,
                      McapRecordWriter,
                      RecordedMessage,
                      describe_mcap,
                      read_mcap,
                      read_metadata,
                      verify_mcap,
)

__all__ = ["McapRecordWriter", "RecordedMessage", "ChannelSummary", "McapReadError", "read_mcap", "describe_mcap",
           "read_metadata", "verify_mcap"]
