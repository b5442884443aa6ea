"""Recording and playback of topics as MCAP files (``dptpu record`` / ``dptpu play``).

- :mod:`.mcap_io`: :class:`McapRecordWriter`, :func:`read_mcap`, :func:`describe_mcap`, :func:`verify_mcap`
  (no graph needed).
- :mod:`.mcap_integrity`: the file's CRCs (chunks, data section, summary) checked, the first fault's offset named.
- :mod:`.ros2_cdr`: ROS types <-> ROS 2 ``.msg`` schemas and CDR dicts (mcap-ros2-support).
- :mod:`.msgpack_records`: the ``dptpu-msgpack`` encoding of the scanner's own types.
- :mod:`.recorder`, :mod:`.player`: subscribe and write, read and publish (they use the graph runtime).

The file layout and both encodings are specified in ``docs/recording.md``.
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
