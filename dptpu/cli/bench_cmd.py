"""``dptpu bench fpp``: speed of ``dptpu.fpp`` against references, each pair in the same run (not a test).
``dptpu bench transport``: the graph runtime against raw pyzmq (``benchmarks/transport_bench.py``).
``dptpu bench twin``: the digital twin's raycast (and Blender) renderer (``benchmarks/twin_bench.py``).
``dptpu bench pipeline``: the whole scanner graph end to end on the sim rig (``benchmarks/pipeline_bench.py``).
``dptpu bench bridge``: the ROS 2 (DDS) bridge with 640x480 clouds (``benchmarks/bridge_bench.py``).

The benchmark code is ``benchmarks/fpp_bench.py`` of the source tree, next to the ``dptpu`` package folder;
it is not part of the installed package, so this command loads it from there and says so when it is missing
(``dptpu`` installed from a wheel instead of a source checkout). What is measured, and against what, is
written in that file's docstring and in ``docs/benchmarks.md``.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

#: Name under which the benchmark file is registered in ``sys.modules`` once loaded.
MODULE_NAME = "dptpu_benchmarks_fpp_bench"
#: The same for ``benchmarks/transport_bench.py`` (``dptpu bench transport``).
TRANSPORT_MODULE_NAME = "dptpu_benchmarks_transport_bench"
#: The same for ``benchmarks/twin_bench.py`` (``dptpu bench twin``).
TWIN_MODULE_NAME = "dptpu_benchmarks_twin_bench"
#: The same for ``benchmarks/pipeline_bench.py`` (``dptpu bench pipeline``).
PIPELINE_MODULE_NAME = "dptpu_benchmarks_pipeline_bench"


def benchmarks_dir() -> Path:
    """The source tree's ``benchmarks`` folder: ``<repo>/benchmarks``, beside the ``dptpu`` package."""
    import dptpu

    return Path(dptpu.__file__).resolve().parents[1] / "benchmarks"


def load_fpp_bench():
    """Import ``benchmarks/fpp_bench.py`` as a module (once per process); see :func:`load_bench`."""
    return load_bench("fpp_bench.py", MODULE_NAME)


def load_transport_bench():
    """Import ``benchmarks/transport_bench.py`` as a module (once per process); see :func:`load_bench`."""
    return load_bench("transport_bench.py", TRANSPORT_MODULE_NAME)


def load_bench(file_name: str, module_name: str):
    """Import ``benchmarks/<file_name>`` as module ``module_name`` (once per process).

    Raises
    ------
    FileNotFoundError
        When the file is absent, naming the path looked at and what to do.
    """
    path = benchmarks_dir() / file_name
    loaded = sys.modules.get(module_name)
    if loaded is not None and Path(getattr(loaded, "__file__", "")) == path:
        return loaded
    if not path.is_file():
        raise FileNotFoundError(
            f"benchmark code not found at {path}: `dptpu bench` runs from a source checkout of dptpu "
            "(the benchmarks/ folder is not installed with the package); clone the repository and "
            f"`pip install -e .` it, or run `python benchmarks/{file_name}` there"
        )
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # before exec: dataclasses and pickling look modules up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[module_name]
        raise
    return module


def register(subparsers) -> None:
    parser = subparsers.add_parser("bench", help="benchmarks against reference implementations (not tests)")
    targets = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    fpp = targets.add_parser(
        "fpp",
        help="phase (vs OpenCV PSP), MF/MW/NT unwrapping (vs bare numpy), triangulation (vs per-pixel solve)",
        description="Times dptpu.fpp against reference implementations side by side on a synthetic "
                    "scene and checks that each pair gives the same numbers. Ratios are reference / ours.",
    )
    fpp.add_argument("--json", action="store_true", help="print the report as one JSON object")
    fpp.add_argument("--repeats", type=int, default=None, help="timed runs per measurement (default 5)")
    fpp.add_argument("--size", default=None, help="camera image size WIDTHxHEIGHT, at least 96x64 (default 640x480)")
    fpp.add_argument("--subset", type=int, default=None,
                     help="pixels on which the per-pixel reference triangulation is timed (default 2000)")
    fpp.set_defaults(func=run_fpp)
    transport = targets.add_parser(
        "transport", help="graph runtime vs raw pyzmq: 7.4 MB throughput and 64-byte round-trip latency",
        description="Two processes over ipc, ours (dptpu.graph publisher -> subscription) and raw pyzmq side by "
                    "side: throughput of a 24x480x640 uint8 message and 64-byte round-trip p50/p99. Ratios are "
                    "ours / raw (see docs/benchmarks.md).")
    transport.add_argument("--json", action="store_true", help="print the report as one JSON object")
    transport.add_argument("--size", choices=("full", "small"), default="full",
                           help="full: 24x480x640 (default); small: 2x48x64 and few messages (for tests)")
    transport.add_argument("--messages", type=int, default=None, help="timed messages per round (default 100)")
    transport.add_argument("--rounds", type=int, default=None, help="rounds of each measurement (default 3)")
    transport.add_argument("--round-trips", type=int, default=None,
                           help="timed round trips per round (default 2000)")
    transport.add_argument("--window", type=int, default=None, help="messages in flight (default 4)")
    transport.add_argument("--no-pin", action="store_true",
                           help="let the OS place the processes (default: senders on the first half of the CPUs, "
                                "receivers on the second half)")
    transport.set_defaults(func=run_transport)
    twin = targets.add_parser(
        "twin", help="digital twin: raycast render of a 640x480 24-frame capture, dataset scenes per minute, Blender",
        description="Times the twin's raycast renderer (trace + image formation of 96x12,1x12) on a random scene and "
                    "the standard sphere, dataset scenes per minute through dptpu.sim, and with --blender the "
                    "Blender seconds per frame and the raycast/Blender ratio (benchmarks/twin_bench.py).")
    twin.add_argument("--json", action="store_true", help="print the report as one JSON object")
    twin.add_argument("--repeats", type=int, default=None, help="timed runs (default 3)")
    twin.add_argument("--size", default=None, help="camera size WIDTHxHEIGHT (default 640x480)")
    twin.add_argument("--scenes", type=int, default=None, help="dataset scenes timed (default 5)")
    twin.add_argument("--blender", action="store_true", help="also time dptpu.sim.blender (needs setup-blender)")
    twin.add_argument("--blender-samples", type=int, default=16, help="Cycles samples per pixel (default 16)")
    twin.set_defaults(func=run_twin)
    pipeline = targets.add_parser(
        "pipeline", help="scanner graph end to end: scans/s and latency p50/p99 at 640x480, 2x12 and 2x3 steps",
        description="Runs launch/sim_rig.yaml as real processes with the sim as fast as possible and times scans per "
                    "second, latency from trigger to cloud (p50, p99) and the ratio to the paper's camera "
                    "(acA640-750: 31.25 scans/s at 24 frames, 125 at 6), classical and DP-TPU "
                    "(benchmarks/pipeline_bench.py).")
    pipeline.add_argument("--json", action="store_true", help="print the report as one JSON object")
    pipeline.add_argument("--size", default="640x480", help="camera size WIDTHxHEIGHT (default 640x480)")
    pipeline.add_argument("--scans", type=int, default=30, help="timed scans per configuration (default 30)")
    pipeline.add_argument("--warmup", type=int, default=5, help="scans before timing starts (default 5)")
    pipeline.add_argument("--in-flight", type=int, default=2, help="scans started ahead (default 2)")
    pipeline.add_argument("--steps", default="12,3", help="12 (2 x 12-step) and/or 3 (2 x 3-step); default 12,3")
    pipeline.add_argument("--model", default=None, help="DP-TPU .onnx model (default: the shipped one, if any)")
    pipeline.add_argument("--classical-only", action="store_true", help="skip DP-TPU even when a model exists")
    pipeline.add_argument("--timeout", type=float, default=600.0, help="seconds per configuration (default 600)")
    pipeline.set_defaults(func=run_pipeline)
    bridge = targets.add_parser(
        "bridge", help="ROS 2 bridge: 640x480 clouds/s and latency added over the graph's own topic (p50/p99)",
        description="Runs dptpu.nodes.ros2_bridge as a process, publishes 640x480 organized clouds on the graph, and "
                    "takes them from the graph and from Cyclone DDS (rt/scanner/points, loopback) side by side "
                    "(benchmarks/bridge_bench.py).")
    bridge.add_argument("--json", action="store_true", help="print the report as one JSON object")
    bridge.add_argument("--size", choices=("full", "small"), default="full", help="full: 640x480; small: 64x48")
    bridge.add_argument("--clouds", type=int, default=None, help="clouds per measurement (default 40; small 10)")
    bridge.add_argument("--rate", type=float, default=None, help="clouds/s of the latency run (default 5)")
    bridge.add_argument("--window", type=int, default=None, help="clouds in flight, throughput run (default 2)")
    bridge.add_argument("--domain", type=int, default=None, help="DDS domain (default 199)")
    bridge.add_argument("--max-message-size", type=int, default=None, help="Cyclone MaxMessageSize, bytes")
    bridge.add_argument("--receive-buffer", default=None, help="Cyclone SocketReceiveBufferSize min, e.g. 4MB")
    bridge.set_defaults(func=run_bridge)


def run_fpp(args) -> int:
    """Load the benchmark from the source tree and run it; 0 if every pair agrees, 1 if not."""
    bench = load_fpp_bench()
    try:
        return bench.run(args)
    except RuntimeError as exc:  # OpenCV without the contrib structured_light module
        print(f"dptpu bench: error: {exc}", file=sys.stderr)
        return 2


def run_transport(args) -> int:
    """Load ``benchmarks/transport_bench.py`` and run it; 0 if every message arrived intact, 1 if not."""
    return load_transport_bench().run(args)


def run_twin(args) -> int:
    """Load ``benchmarks/twin_bench.py`` and run it (``dptpu bench twin``); 0."""
    return load_bench("twin_bench.py", TWIN_MODULE_NAME).run(args)


def run_pipeline(args) -> int:
    """Load ``benchmarks/pipeline_bench.py`` and run it (``dptpu bench pipeline``); 0, 2 for bad options."""
    return load_bench("pipeline_bench.py", PIPELINE_MODULE_NAME).run(args)


def run_bridge(args) -> int:
    """Load ``benchmarks/bridge_bench.py`` and run it (``dptpu bench bridge``); 0 if every cloud arrived intact."""
    return load_bench("bridge_bench.py", "dptpu_benchmarks_bridge_bench").run(args)
