"""What the cloud's fields of issue 18 cost per scan: the normals, the wider interleave, and the ROS 2 CDR of the
recorder.

Run it as ``dptpu bench cloud_fields [--size 640x480] [--number N] [--repeats R] [--json]`` (or
``python benchmarks/cloud_fields_bench.py``). Not a test: nothing asserts a time.

- ``normals_w3``, ``normals_w1``: :func:`dptpu.fpp.organized_normals.organized_normals` on a planar cloud of a
  tilted plane (window 3, the cloud node's default, and 1);
- ``merge_6``, ``merge_9``: the cloud node's ``cv2.merge`` of the float32 planes without and with the normals;
- ``cdr_encode_phase_maps``, ``cdr_decode_phase_maps``: :mod:`dptpu.messages.cdr` on a two-frequency ``PhaseMaps``
  (what the recorder writes per scan on ``/scanner/phase``).

Times are milliseconds of CPU a call (``time.process_time``: the work is single-threaded, and the CPU clock does not
count other jobs of a shared machine), best of ``--repeats`` runs of ``--number`` calls, and their median.
"""
from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from dptpu.fpp.organized_normals import organized_normals
from dptpu.messages import Header, PhaseMaps
from dptpu.messages.cdr import decode_cdr, encode_cdr


def _times_ms(call, number: int, repeats: int) -> dict[str, float]:
    runs = []
    for _ in range(repeats):
        start = time.process_time()
        for _ in range(number):
            call()
        runs.append(1e3 * (time.process_time() - start) / number)
    return {"best_ms": round(min(runs), 3), "median_ms": round(float(np.median(runs)), 3)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="dptpu bench cloud_fields", description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480", help="camera WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--number", type=int, default=5, help="calls per run (default 5)")
    parser.add_argument("--repeats", type=int, default=5, help="runs (default 5)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    planes = np.empty((3, height, width), np.float32)  # a tilted plane at 0.85 m, camera optical frame
    z = 0.85 + 0.0001 * u
    planes[0], planes[1], planes[2] = (u - width / 2) / 1200 * z, (v - height / 2) / 1200 * z, z
    normals = np.empty_like(planes)
    six = [planes[0], planes[1], planes[2], planes[2], planes[1], planes[0]]
    nine = six + list(normals)
    maps = PhaseMaps(header=Header(), sequence_id=1, fringe_axis="x", projector_width=912, projector_height=1140,
                     frequencies=np.array([64.0, 1.0]),
                     phases=np.random.default_rng(0).random((2, height, width), dtype=np.float32),
                     modulation=np.random.default_rng(1).random((2, height, width), dtype=np.float32),
                     valid=np.ones((height, width), bool))
    cdr = encode_cdr(maps)
    results = {
        "normals_w3": _times_ms(lambda: organized_normals(planes.transpose(1, 2, 0), window_px=3,
                                                          out=normals.transpose(1, 2, 0)), args.number, args.repeats),
        "normals_w1": _times_ms(lambda: organized_normals(planes.transpose(1, 2, 0), window_px=1,
                                                          out=normals.transpose(1, 2, 0)), args.number, args.repeats),
        "merge_6": _times_ms(lambda: cv2.merge(six), args.number, args.repeats),
        "merge_9": _times_ms(lambda: cv2.merge(nine), args.number, args.repeats),
        "cdr_encode_phase_maps": _times_ms(lambda: encode_cdr(maps), args.number, args.repeats),
        "cdr_decode_phase_maps": _times_ms(lambda: decode_cdr(PhaseMaps, cdr), args.number, args.repeats),
    }
    if args.json:
        print(json.dumps({"size": args.size, "results": results}))
    else:
        for name, figures in results.items():
            print(f"{name:24s} best {figures['best_ms']:8.3f} ms, median {figures['median_ms']:8.3f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
