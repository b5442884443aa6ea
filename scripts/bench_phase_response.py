"""What the projector's phase response costs the phase computation: `ProjectorPhaseResponse.correct` beside Eq. (2).

    .venv/bin/python scripts/bench_phase_response.py [--size 640x480] [--repeats 30]

Interleaved, on one float32 3-step sequence of random 8-bit frames: the wrapped phase (:func:`dptpu.fpp.phase.
wrapped_phase`, float32) and the correction of that phase by a three-term 3-step response (the CFPE projector's,
docs/calibration.md). Prints the median of each, milliseconds (docs/benchmarks.md, "The projector's phase response").
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.phase_harmonics import HarmonicPhaseError, ProjectorPhaseResponse

#: The CFPE projector's 3-step response (dptpu calibrate response on scenes 04, 06, 08).
CFPE_RESPONSE = ProjectorPhaseResponse({3: HarmonicPhaseError(3, 0.0008, -0.1575, (0.0001, 0.0), (0.0144, -0.0011))})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--repeats", type=int, default=30, help="timed runs of each (default 30)")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    frames = np.random.default_rng(0).integers(0, 256, (3, height, width), dtype=np.uint8)
    psi = wrapped_phase(frames, dtype=np.float32).phase
    CFPE_RESPONSE.correct(psi, 3)  # the table is built once, on first use
    phase_s, correct_s = [], []
    for _ in range(args.repeats):
        start = time.perf_counter()
        wrapped_phase(frames, dtype=np.float32)
        phase_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        CFPE_RESPONSE.correct(psi, 3)
        correct_s.append(time.perf_counter() - start)
    print(f"{width}x{height}: 3-step wrapped phase (float32) median {1e3 * np.median(phase_s):.2f} ms; "
          f"ProjectorPhaseResponse.correct median {1e3 * np.median(correct_s):.2f} ms ({args.repeats} each, "
          f"interleaved)")


if __name__ == "__main__":
    main()
