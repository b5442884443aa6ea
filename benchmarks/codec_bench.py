"""Cost of the wire codec per message of the scanner graph: ``encode`` and ``decode`` against the general path.

Run it as ``dptpu bench codec [--json] [--size 640x480] [--number N] [--repeats R]`` (or
``python benchmarks/codec_bench.py``). Not a test: nothing asserts a time; every message is decoded back and
compared with what was encoded, by both paths, and the report says whether they agree.

Every message the scanner graph sends (docs/scanner.md) is encoded and decoded here as the graph does it:
``Trigger``, ``ScanStatus``, ``FringeFrame`` (a mono8 camera frame), ``CameraInfo``, ``PhaseMaps`` (two
frequencies), ``AbsolutePhase`` and the organized ``PointCloud2`` of the cloud node (x, y, z, intensity,
quality, float32), all at ``--size``. Arrays travel as views (zero-copy) on both paths, so the times are the
per-message Python and msgpack work that the runtime adds to every publish and every receive. The frames
decoded are ``zmq.Frame`` objects, received over an inproc socket as a subscription receives them.

- ``ours``: :func:`dptpu.messages.encoder.encode` / :func:`~dptpu.messages.decoder.decode`, which take the
  class's precomputed plan (the fast path) and fall back to the general path for anything it does not
  accept;
- ``general`` (the reference, what every message with a nested field took before the fast path covered nested
  messages): :func:`dptpu.messages.encoder.encode_checked` / :func:`~dptpu.messages.decoder.decode_checked`,
  which check and convert field by field and name the first problem.

Times are microseconds of CPU a message (``timeit`` with ``time.process_time`` as its clock: the work is
single-threaded, and the CPU clock does not count the time other jobs of a shared machine take), best of
``--repeats`` runs of ``--number`` calls, and the median of those runs; ``speedup = general / ours`` from the
best times.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import timeit

import numpy as np

DEFAULT_SIZE = (480, 640)


def scanner_messages(height: int, width: int) -> dict:
    """One message of each type the scanner graph sends, at ``height x width``, with seeded content."""
    from dptpu.messages import CameraInfo, Header, Image, PointCloud2, Time
    from dptpu.messages.scanner import (
        AbsolutePhase,
        FringeFrame,
        PhaseMaps,
        ScanStatus,
        Trigger,
    )

    rng = np.random.default_rng(0)
    header = Header(stamp=Time(sec=1_700_000_000, nanosec=123_456_789), frame_id="scanner_optical_frame")
    trigger = Trigger(header=header, sequence_id=7, pattern_index=5, pattern_count=24, frequency=64.0, steps=12,
                      step=5)
    frame = rng.integers(0, 256, (height, width), dtype=np.uint8)
    phases = rng.uniform(0, 2 * np.pi, (2, height, width)).astype(np.float32)
    valid = rng.random((height, width)) > 0.1
    absolute = (phases[0] * 64).astype(np.float32)
    points = rng.standard_normal((height, width, 5)).astype(np.float32)
    return {
        "Trigger": trigger,
        "ScanStatus": ScanStatus(header=header, sequence_id=7, level=0, state="done", reason="", node="/cloud",
                                 frames_expected=24, frames_received=24, valid_pixels=int(valid.sum()),
                                 total_pixels=height * width, duration_s=0.05),
        "FringeFrame": FringeFrame(image=Image.from_array(frame, header=header), trigger=trigger),
        "CameraInfo": CameraInfo.from_intrinsics([[2600.0, 0, width / 2], [0, 2600.0, height / 2], [0, 0, 1]],
                                                 [0.01, -0.02, 0.0, 0.0, 0.0], width, height, header=header),
        "PhaseMaps": PhaseMaps(header=header, sequence_id=7, projector_width=912, projector_height=1140,
                               frequencies=np.array([64.0, 1.0]), phases=phases, modulation=phases.copy(),
                               valid=valid),
        "AbsolutePhase": AbsolutePhase(header=header, sequence_id=7, frequency=64.0, projector_width=912,
                                       projector_height=1140, absolute_phase=absolute,
                                       fringe_order=np.floor(absolute / (2 * np.pi)).astype(np.int32), valid=valid,
                                       reliability=phases[1], method="mf"),
        "PointCloud2": PointCloud2.from_array(points, ["x", "y", "z", "intensity", "quality"], header=header),
    }


def _same(a, b) -> bool:
    """Whether two messages are equal field by field (arrays by value)."""
    if type(a) is not type(b):
        return False
    for spec in type(a).FIELDS:
        x, y = getattr(a, spec.name), getattr(b, spec.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif isinstance(x, list):
            if len(x) != len(y) or not all(_same(i, j) for i, j in zip(x, y)):
                return False
        elif hasattr(x, "FIELDS"):
            if not _same(x, y):
                return False
        elif x != y:
            return False
    return True


def _time(stmt, number: int, repeats: int) -> dict:
    runs = [t / number * 1e6 for t in timeit.repeat(stmt, number=number, repeat=repeats, timer=time.process_time)]
    return {"best_us": min(runs), "median_us": statistics.median(runs)}


def measure(size=DEFAULT_SIZE, number: int = 2000, repeats: int = 5) -> dict:
    import zmq

    from dptpu.messages import decoder, encoder

    topic = b"/bench/codec"
    results = {}
    context = zmq.Context()
    sender, receiver = context.socket(zmq.PAIR), context.socket(zmq.PAIR)
    sender.bind("inproc://codec-bench")
    receiver.connect("inproc://codec-bench")
    for name, msg in scanner_messages(*size).items():
        sender.send_multipart(encoder.encode(topic, msg), copy=False)
        frames = receiver.recv_multipart(copy=False)  # zmq.Frame objects, as a subscription receives them
        general_frames = encoder.encode_checked(topic, msg)
        decoded = decoder.decode(frames)[1]
        decoded_general = decoder.decode_checked(general_frames)[1]
        entry = {
            "header_bytes": len(frames[1].bytes),
            "array_bytes": sum(frame.buffer.nbytes for frame in frames[2:]),
            "same_header": frames[1].bytes == bytes(general_frames[1]),
            "round_trip_equal": _same(decoded, msg) and _same(decoded_general, msg),
            "encode": {"ours": _time(lambda m=msg: encoder.encode(topic, m), number, repeats),
                       "general": _time(lambda m=msg: encoder.encode_checked(topic, m), number, repeats)},
            "decode": {"ours": _time(lambda f=frames: decoder.decode(f), number, repeats),
                       "general": _time(lambda f=frames: decoder.decode_checked(f), number, repeats)},
        }
        for part in ("encode", "decode"):
            entry[part]["speedup"] = entry[part]["general"]["best_us"] / entry[part]["ours"]["best_us"]
        results[name] = entry
    sender.close(0)
    receiver.close(0)
    context.term()
    return {"size": f"{size[1]}x{size[0]}", "number": number, "repeats": repeats, "messages": results,
            "all_equal": all(entry["round_trip_equal"] and entry["same_header"] for entry in results.values())}


def format_report(report: dict) -> str:
    title = (f"dptpu bench codec ({report['size']}; best of {report['repeats']} x {report['number']} calls, "
             "us a message)")
    columns = (f"{'message':<14} {'header B':>8} {'arrays B':>10}   {'encode ours':>11} {'general':>8} {'x':>5}   "
               f"{'decode ours':>11} {'general':>8} {'x':>5}  equal")
    lines = [title, columns]
    for name, entry in report["messages"].items():
        enc, dec = entry["encode"], entry["decode"]
        lines.append(f"{name:<14} {entry['header_bytes']:>8} {entry['array_bytes']:>10}   "
                     f"{enc['ours']['best_us']:>11.1f} {enc['general']['best_us']:>8.1f} {enc['speedup']:>5.1f}   "
                     f"{dec['ours']['best_us']:>11.1f} {dec['general']['best_us']:>8.1f} {dec['speedup']:>5.1f}  "
                     f"{'yes' if entry['round_trip_equal'] and entry['same_header'] else 'NO'}")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="dptpu bench codec",
                                     description="encode/decode of the scanner's messages: fast path vs general path")
    parser.add_argument("--size", default="640x480", metavar="WxH", help="image size (640x480)")
    parser.add_argument("--number", type=int, default=2000, help="calls per timed run (2000)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs; the best and the median are reported (5)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    if args.number < 1 or args.repeats < 1:
        parser.error("--number and --repeats must be >= 1")
    from dptpu.sim.rig import parse_size

    try:
        width, height = parse_size(args.size)
    except ValueError as exc:
        parser.error(f"--size: {exc}")
    report = measure((height, width), args.number, args.repeats)
    print(json.dumps(report, indent=2) if args.json else format_report(report))
    return 0 if report["all_equal"] else 1


if __name__ == "__main__":
    sys.exit(main())
