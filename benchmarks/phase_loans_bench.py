"""What the phase node's loans save: its scan publication with loaned segments against new arrays (issue 20).

Run it as ``dptpu bench phase_loans [--size 640x480] [--steps 12,3] [--scans 10] [--pairs 3] [--json]`` (or
``python benchmarks/phase_loans_bench.py``). Not a test: nothing asserts a time.

One process, shared memory on in both variants: the phase node in a :class:`dptpu.nodes.harness.NodeHarness` (real
sockets, one thread) takes ``--scans`` two-frequency scans of ramp fringes (64 and 1 periods, 1 DN of noise) and
publishes their PhaseMaps and texture through shared memory, either

- ``loaned``: computed in place in segments its publishers lend (``Publisher.borrow_loaned_arrays``), published
  without a copy (the node as it is), or
- ``copied``: computed into new arrays that ``publish`` copies into segments (``Publisher.can_loan_messages``
  patched to False: the node before the loans).

The figure is the main thread's CPU (``time.thread_time``) of the node's ``_publish_scan`` a scan (the last entry's
Eq. (2) sums, the maps, the texture, the three messages), after two warm-up scans, in ``--pairs`` alternating runs
of each variant; the report gives every run and the medians.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from dptpu.graph.publisher import Publisher
from dptpu.messages import FringeFrame, Image, PhaseMaps
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode

FREQUENCIES = (64.0, 1.0)
WARMUP_SCANS = 2


def ramp_stack(frequency: float, steps: int, size: tuple[int, int], rng) -> np.ndarray:
    """(steps, H, W) uint8 frames of vertical fringes of ``frequency`` periods across the width, 1 DN of noise."""
    width, height = size
    columns = np.arange(width)[None, None, :]
    n = np.arange(steps)[:, None, None]
    fringes = 128 + 90 * np.cos(2 * np.pi * frequency * columns / width - 2 * np.pi * n / steps)
    return np.clip(np.round(fringes + rng.normal(0, 1, (steps, height, width))), 0, 255).astype(np.uint8)


def publication_ms(*, loaned: bool, steps: int, size: tuple[int, int], scans: int) -> float:
    """CPU ms of the phase node's ``_publish_scan`` a scan, with its loans or with new arrays copied by publish."""
    rng = np.random.default_rng(0)
    stacks = [ramp_stack(frequency, steps, size, rng) for frequency in FREQUENCIES]
    original = Publisher.can_loan_messages
    if not loaned:
        Publisher.can_loan_messages = lambda self, nbytes=None: False  # the A/B: the node before the loans
    try:
        spent = [0.0]
        with NodeHarness() as harness:
            node = harness.start(PhaseNode, timeout_s=5.0)
            camera = harness.publisher(FringeFrame, "/camera/image_raw")
            phase = harness.collect(PhaseMaps, "/scanner/phase")
            texture = harness.collect(Image, "/scanner/texture")
            harness.connect()
            publish_scan = node._publish_scan

            def timed(scan):
                start = time.thread_time()
                publish_scan(scan)
                spent[0] += time.thread_time() - start

            node._publish_scan = timed  # the timed call
            for sequence_id in range(1, WARMUP_SCANS + scans + 1):
                if sequence_id == WARMUP_SCANS + 1:
                    spent[0] = 0.0
                for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=sequence_id):
                    camera.publish(frame)
                harness.wait(phase, 1)
                harness.wait(texture, 1)
                phase.messages.clear()
                texture.messages.clear()
            if node.phase_publisher.shared_count != WARMUP_SCANS + scans:
                raise RuntimeError("the PhaseMaps did not all go through shared memory")
        return 1e3 * spent[0] / scans
    finally:
        Publisher.can_loan_messages = original  # restored


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="dptpu bench phase_loans", description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="640x480", help="camera size WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--steps", default="12,3", help="steps of each frequency's sequence, runs of each (12,3)")
    parser.add_argument("--scans", type=int, default=10, help="timed scans a run (default 10)")
    parser.add_argument("--pairs", type=int, default=3, help="alternating runs of each variant (default 3)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    report = {"size": args.size, "scans": args.scans, "pairs": args.pairs, "runs": {}}
    for steps in (int(v) for v in args.steps.split(",")):
        runs: dict[str, list[float]] = {"loaned": [], "copied": []}
        for _ in range(args.pairs):
            for variant in runs:
                runs[variant].append(publication_ms(loaned=variant == "loaned", steps=steps, size=size,
                                                    scans=args.scans))
        report["runs"][f"2x{steps}"] = {variant: {"ms": [round(v, 2) for v in values],
                                                  "median_ms": round(float(np.median(values)), 2)}
                                        for variant, values in runs.items()}
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for name, variants in report["runs"].items():
            print(f"{name}: " + ", ".join(f"{variant} {v['median_ms']:.2f} ms (runs {v['ms']})"
                                          for variant, v in variants.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
