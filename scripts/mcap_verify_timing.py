"""What checking an MCAP file's CRCs costs beside reading it (issue 19): ``verify_mcap`` against ``read_mcap``.

    PYTHONPATH=. .venv/bin/python scripts/mcap_verify_timing.py [--images 200] [--size 640x480]

Writes ``--images`` mono8 images (a fixed pattern plus seeded noise, so zstd compresses a little) with each
compression to a temporary folder, then times :func:`dptpu.tools.recording.verify_mcap` (every CRC, every chunk
decompressed) and :func:`dptpu.tools.recording.read_mcap` with ``verify=False`` (decoding every message, chunk CRCs
checked as read). Prints a Markdown table (docs/benchmarks.md, "MCAP integrity check").
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from dptpu.messages import Image
from dptpu.tools.recording import McapRecordWriter, read_mcap, verify_mcap
from dptpu.tools.recording.mcap_io import COMPRESSIONS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=200)
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    rng = np.random.default_rng(0)
    pattern = (np.arange(width * height).reshape(height, width) % 251).astype(np.uint8)
    print("| compression | file (MB) | verify_mcap (s) | read_mcap, verify=False (s) |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for compression in COMPRESSIONS:
            path = Path(folder) / f"{compression}.mcap"
            with McapRecordWriter(path, compression=compression) as writer:
                for index in range(args.images):
                    noise = rng.integers(0, 8, pattern.shape, dtype=np.uint8)
                    writer.write("/camera/image_raw", Image.from_array(pattern + noise), 1_000 + index)
            started = time.perf_counter()
            verify_mcap(path)
            verify_s = time.perf_counter() - started
            started = time.perf_counter()
            count = sum(1 for _ in read_mcap(path, verify=False))
            read_s = time.perf_counter() - started
            assert count == args.images
            print(f"| {compression} | {path.stat().st_size / 1e6:.1f} | {verify_s:.2f} | {read_s:.2f} |")


if __name__ == "__main__":
    main()
