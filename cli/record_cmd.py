"""``dptpu record`` and ``dptpu play``: topics to an MCAP file and back (like ``ros2 bag record/play``).

- ``dptpu record -o FILE.mcap TOPIC... [--duration S] [--max-messages N] [--compression C]`` subscribes to
  each topic as soon as the graph shows a publisher of it (type and QoS from discovery) and writes
  every message with its receive time. It stops on Ctrl-C / SIGTERM, after ``--duration`` seconds or
  after ``--max-messages`` messages in total, closes the file properly and prints the counts. Exit
  code 0, or 1 when a requested topic never appeared.
- ``dptpu play FILE.mcap [--rate R] [--loop] [--topics T...] [--delay S] [--wait-for-subscribers S]``
  publishes the recorded messages on their topics with the recorded timing divided by ``--rate``.

The file format (every channel ROS 2 CDR with a ``ros2msg`` schema and ``offered_qos_profiles``) is in
``docs/recording.md``.
"""
from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

from dptpu.cli.conventions import parse_list


def register(subparsers) -> None:
    record = subparsers.add_parser(
        "record", help="record topics to an MCAP file (ROS 2 CDR for sensor_msgs)",
        description="Subscribe to TOPICs as they appear in the graph and write every message, with its receive "
                    "time, to an MCAP file that ROS 2 (ros2 bag, mcap storage) and Foxglove open. Stops on "
                    "Ctrl-C/SIGTERM, --duration or --max-messages. See docs/recording.md.")
    record.add_argument("topics", nargs="+", metavar="TOPIC", help="topics to record, e.g. /camera/image_raw")
    record.add_argument("-o", "--output", required=True, metavar="FILE.mcap", help="the MCAP file to write")
    record.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after S seconds (default: until Ctrl-C)")
    record.add_argument("--max-messages", type=int, default=None, metavar="N",
                        help="stop after N messages in total over all topics")
    record.add_argument("--compression", choices=("zstd", "lz4", "none"), default="zstd",
                        help="chunk compression (default zstd, as ros2 bag)")
    record.add_argument("--domain-id", type=int, default=None, metavar="ID",
                        help="graph domain (default: $DPTPU_DOMAIN_ID, $ROS_DOMAIN_ID, 0)")
    record.set_defaults(func=run_record)

    play = subparsers.add_parser(
        "play", help="publish the messages of an MCAP file on their topics",
        description="Publish the recorded messages of an MCAP file on their topics, in log-time order, with the "
                    "recorded spacing divided by --rate. See docs/recording.md.")
    play.add_argument("file", metavar="FILE.mcap", help="the MCAP file to play")
    play.add_argument("-r", "--rate", type=float, default=1.0, help="speed factor (default 1.0; 2 = twice as fast)")
    play.add_argument("-l", "--loop", action="store_true", help="play again from the start until Ctrl-C")
    play.add_argument("--topics", nargs="+", default=None, metavar="TOPIC,...",
                      help="play only these topics, comma separated (e.g. /scanner/points,/scanner/depth)")
    play.add_argument("-d", "--delay", type=float, default=0.0, metavar="S",
                      help="seconds to wait after creating the publishers (default 0)")
    play.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                      help="wait up to S seconds until every topic has a subscription (default 0: do not wait)")
    play.add_argument("--domain-id", type=int, default=None, metavar="ID",
                      help="graph domain (default: $DPTPU_DOMAIN_ID, $ROS_DOMAIN_ID, 0)")
    play.set_defaults(func=run_play)


@contextmanager
def _stop_on_signals():
    """Ctrl-C and SIGTERM set the yielded event (so a write in progress completes) instead of raising."""
    stop = threading.Event()
    handled = (signal.SIGINT, signal.SIGTERM)
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum in handled:
            previous[signum] = signal.signal(signum, lambda _signum, _frame: stop.set())
    try:
        yield stop
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def run_record(args) -> int:
    """Record until stopped; print a table of counts; 1 when a topic never appeared, else 0."""
    from dptpu.tools.recording.recorder import record  # deferred: CLI start-up (the runtime and mcap)

    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration must be > 0 seconds; got {args.duration}")
    if args.max_messages is not None and args.max_messages < 1:
        raise ValueError(f"--max-messages must be >= 1; got {args.max_messages}")

    def subscribed(topic: str, type_name: str) -> None:
        print(f"[record] subscribed to {topic} [{type_name}]", file=sys.stderr, flush=True)

    print(f"[record] recording {len(args.topics)} topic(s) to {args.output}; Ctrl-C to stop", file=sys.stderr,
          flush=True)
    with _stop_on_signals() as stop:
        result = record(args.output, args.topics, duration_s=args.duration, max_messages=args.max_messages,
                        compression=args.compression, stop_event=stop, domain_id=args.domain_id,
                        on_subscribed=subscribed)
    width = max(len(topic) for topic in result.counts)
    print(f"recorded {result.total} message(s) in {result.duration_s:.1f} s to {result.path} "
          f"(stopped: {result.stop_reason})")
    for topic, count in result.counts.items():
        type_name = result.types.get(topic, "never appeared")
        dropped = result.dropped.get(topic, 0)
        note = f", {dropped} dropped" if dropped else ""
        print(f"  {topic:<{width}}  {count:>8}  [{type_name}]{note}")
    return 1 if result.missing else 0


def run_play(args) -> int:
    """Play the file; print what was published; 0 on success."""
    from dptpu.tools.recording.player import play  # deferred: CLI start-up (the runtime and mcap)

    def ready(result) -> None:
        planned = ", ".join(f"{topic} [{type_name}]" for topic, type_name in result.types.items())
        print(f"[play] playing {args.file} at rate {args.rate:g}{' in a loop' if args.loop else ''}: {planned}",
              file=sys.stderr, flush=True)
        for topic, reason in result.skipped.items():
            print(f"[play] skipping {topic}: {reason}", file=sys.stderr, flush=True)
        for topic in result.unmatched:
            print(f"[play] no subscription on {topic} after {args.wait_for_subscribers:g} s; playing anyway",
                  file=sys.stderr, flush=True)

    topics = None
    if args.topics is not None:
        if len(args.topics) > 1:  # the old space-separated spelling
            raise ValueError(f"--topics takes one comma-separated list: --topics {','.join(args.topics)} "
                             f"(space-separated topics are no longer accepted)")
        topics = list(parse_list(args.topics[0], "--topics", str, example="/scanner/points,/scanner/depth"))
    with _stop_on_signals() as stop:
        result = play(args.file, rate=args.rate, loop=args.loop, topics=topics, delay_s=args.delay,
                      wait_for_subscribers_s=args.wait_for_subscribers, stop_event=stop, domain_id=args.domain_id,
                      on_ready=ready)
    print(f"published {result.total} message(s) in {result.duration_s:.1f} s"
          f"{f' ({result.loops} loop(s))' if args.loop else ''}")
    width = max(len(topic) for topic in result.counts) if result.counts else 0
    for topic, count in result.counts.items():
        print(f"  {topic:<{width}}  {count:>8}  [{result.types[topic]}]")
    return 0
