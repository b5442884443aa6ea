"""Throughput and added latency of the ROS 2 bridge for organized 640x480 clouds (not a test).

Run it as ``dptpu bench bridge [--json] [--size full|small]`` or ``python benchmarks/bridge_bench.py``.

Two OS processes on this machine. The bridge (``python -m dptpu.nodes.ros2_bridge``, default parameters) is the
thing measured. The bench process is the scanner and the robot at once: a graph node publishes
``/scanner/points`` (PointCloud2 of the cloud node's layout, float32 x y z intensity quality, 20 bytes a point,
640x480 = 6,144,000 bytes; ``--size small``: 64x48), subscribes to the same graph topic itself (RELIABLE, depth
10: "the graph's own topic"), and a Cyclone DDS reader takes ``rt/scanner/points`` (ROS 2 default QoS, plain
CDR) from the bridge. Each cloud's header stamp is its publish time (``time.time_ns``); arrival times are taken
when the graph callback runs and when the DDS reader returns the sample.

(a) Added latency: clouds published at ``--rate`` (default 5 per second, well below capacity), ``--clouds`` of
    them (default 40) after 5 warm-ups. Per cloud: graph latency = graph arrival - stamp, DDS latency = DDS
    arrival - stamp, added = DDS latency - graph latency; p50 and p99 of each.
(b) Throughput: ``--clouds`` clouds with at most ``--window`` (default 2) published and not yet taken from DDS,
    so nothing is dropped for lack of flow control; clouds/s = taken / (last DDS arrival - first publish).
    The bridge process's CPU time (``/proc/PID/stat``, every thread) is reported per cloud.

Every cloud taken from DDS is checked byte for byte against the cloud published (4 different random clouds
cycle). Cyclone runs on loopback only (``lo``, multicast off, peer 127.0.0.1) on ``--domain`` (default 199),
and the graph in a fresh ``DPTPU_DISCOVERY_DIR`` under /tmp: the benchmark never meets another graph or a real
ROS 2 network.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

FIELDS = ["x", "y", "z", "intensity", "quality"]
SIZES = {"full": (640, 480), "small": (64, 48)}
POOL = 4
WARMUP = 5
LOOPBACK_URI = ("<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
                "<AllowMulticast>false</AllowMulticast>{extra}</General><Discovery>"
                "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>50</MaxAutoParticipantIndex>"
                "<Peers><Peer Address=\"127.0.0.1\"/></Peers></Discovery>{internal}</Domain></CycloneDDS>")


def _pool(width: int, height: int) -> list[np.ndarray]:
    """``POOL`` random organized clouds (H, W, 5) float32 with 10 % NaN holes, as the cloud node makes them."""
    rng = np.random.default_rng(0)
    clouds = []
    for _ in range(POOL):
        points = rng.normal(0.0, 0.1, size=(height, width, 5)).astype(np.float32)  # (H, W, 5)
        points[..., 2] += 0.8
        points[rng.random((height, width)) < 0.1, :3] = np.nan
        clouds.append(points)
    return clouds


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (every thread)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _quantiles_ms(values_ns: list) -> dict:
    data = np.asarray(values_ns, dtype=np.float64) / 1e6
    return {"p50_ms": float(np.percentile(data, 50)), "p99_ms": float(np.percentile(data, 99)),
            "mean_ms": float(data.mean())}


class _Bench:
    """The bench process's graph node (publisher + subscription) and DDS reader."""

    def __init__(self, width: int, height: int, domain: int):
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from dptpu.graph import Context, Node
        from dptpu.graph.executors import SingleThreadedExecutor
        from dptpu.messages import PointCloud2
        from dptpu.nodes.ros2_bridge.ros2_idl import PointCloud2_
        from dptpu.nodes.ros2_bridge.ros2_qos import ros2_qos

        self.pool = _pool(width, height)
        self.pool_bytes = [cloud.tobytes() for cloud in self.pool]
        self.context = Context()
        self.context.init([], domain_id=0)
        self.node = Node("bridge_bench", context=self.context)
        self.publisher = self.node.create_publisher(PointCloud2, "/scanner/points", 10)
        self.graph_arrival: dict[int, int] = {}
        self.lock = threading.Lock()
        self.node.create_subscription(PointCloud2, "/scanner/points", self._on_graph, 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        self.participant = DomainParticipant(domain)
        qos = ros2_qos("default")
        self.reader = DataReader(self.participant, Topic(self.participant, "rt/scanner/points", PointCloud2_,
                                                         qos=qos), qos=qos)
        self.dds_arrival: dict[int, int] = {}
        self.sent_index: dict[int, int] = {}
        self.corrupt = 0

    def _on_graph(self, msg) -> None:
        with self.lock:
            self.graph_arrival[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = time.time_ns()

    def publish(self, number: int) -> int:
        from dptpu.messages import Header, PointCloud2, Time

        stamp_ns = time.time_ns()
        index = number % POOL
        self.sent_index[stamp_ns] = index
        header = Header(stamp=Time.from_ns(stamp_ns), frame_id="scanner_optical_frame")
        self.publisher.publish(PointCloud2.from_array(self.pool[index], FIELDS, header=header))
        return stamp_ns

    def take(self) -> int:
        """Take what DDS has; returns how many clouds came."""
        samples = self.reader.take(N=8)
        now = time.time_ns()
        count = 0
        for sample in samples:
            if not hasattr(sample, "data"):
                continue
            stamp_ns = sample.header.stamp.sec * 1_000_000_000 + sample.header.stamp.nanosec
            self.dds_arrival[stamp_ns] = now
            index = self.sent_index.get(stamp_ns)
            if index is None or sample.data != self.pool_bytes[index]:
                self.corrupt += 1
            count += 1
        return count

    def wait_dds(self, stamp_ns: int, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while stamp_ns not in self.dds_arrival and time.monotonic() < deadline:
            if not self.take():
                time.sleep(0.0005)
        return stamp_ns in self.dds_arrival

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.context.try_shutdown()


def _resolve(args) -> argparse.Namespace:
    return argparse.Namespace(size=getattr(args, "size", "full") or "full",
                              clouds=getattr(args, "clouds", None) or (40 if args.size != "small" else 10),
                              rate=getattr(args, "rate", None) or 5.0, window=getattr(args, "window", None) or 2,
                              domain=getattr(args, "domain", None) or 199,
                              max_message_size=getattr(args, "max_message_size", None) or 0,
                              receive_buffer=getattr(args, "receive_buffer", None) or "")


def measure(args) -> dict:
    """Start the bridge, run (a) and (b); return the report (see the module docstring)."""
    options = _resolve(args)
    width, height = SIZES[options.size]
    folder = Path(tempfile.mkdtemp(prefix="dbb", dir="/tmp"))
    extra = f"<MaxMessageSize>{options.max_message_size}B</MaxMessageSize>" if options.max_message_size else ""
    internal = (f"<Internal><SocketReceiveBufferSize min=\"{options.receive_buffer}\"/></Internal>"
                if options.receive_buffer else "")
    env_overrides = {"DPTPU_DISCOVERY_DIR": str(folder), "DPTPU_DOMAIN_ID": "0",
                     "CYCLONEDDS_URI": LOOPBACK_URI.format(extra=extra, internal=internal)}
    saved = {name: os.environ.get(name) for name in (*env_overrides, "ROS_DOMAIN_ID")}
    os.environ.update(env_overrides)
    os.environ.pop("ROS_DOMAIN_ID", None)
    repo_root = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=repo_root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    bridge = subprocess.Popen([sys.executable, "-m", "dptpu.nodes.ros2_bridge", "--ros-args", "-p",
                               f"domain_id:={options.domain}", "-p", "capture_service:="], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    bench = None
    try:
        bench = _Bench(width, height, options.domain)
        if not bench.publisher.wait_for_subscriptions(2, timeout_sec=60):
            raise RuntimeError(f"the bridge did not subscribe to /scanner/points within 60 s: "
                               f"{bridge.stderr.read() if bridge.poll() is not None else ''}")
        for attempt in range(200):  # warm-up: until DDS discovery matched and WARMUP clouds went through
            stamp = bench.publish(attempt)
            if bench.wait_dds(stamp, 1.0) and len(bench.dds_arrival) >= WARMUP:
                break
        else:
            raise RuntimeError("no cloud came through the bridge on DDS in 200 tries")

        latency_stamps = []  # (a) paced
        for number in range(options.clouds):
            started = time.monotonic()
            stamp = bench.publish(number)
            latency_stamps.append(stamp)
            bench.wait_dds(stamp, 5.0)
            time.sleep(max(0.0, 1.0 / options.rate - (time.monotonic() - started)))
        time.sleep(0.2)
        with bench.lock:
            pairs = [(bench.graph_arrival[s] - s, bench.dds_arrival[s] - s) for s in latency_stamps
                     if s in bench.graph_arrival and s in bench.dds_arrival]
        graph_ns = [g for g, _ in pairs]
        dds_ns = [d for _, d in pairs]
        added_ns = [d - g for g, d in pairs]

        cpu_before = _cpu_s(bridge.pid)  # (b) windowed
        first_publish = time.time_ns()
        throughput_stamps = []
        while len(throughput_stamps) < options.clouds:
            in_flight = sum(1 for s in throughput_stamps if s not in bench.dds_arrival)
            if in_flight < options.window:
                throughput_stamps.append(bench.publish(len(throughput_stamps)))
            elif not bench.take():
                time.sleep(0.0002)
        bench.wait_dds(throughput_stamps[-1], 10.0)
        cpu_bridge_s = _cpu_s(bridge.pid) - cpu_before
        taken = [bench.dds_arrival[s] for s in throughput_stamps if s in bench.dds_arrival]
        elapsed_s = (max(taken) - first_publish) / 1e9
        report = {
            "machine": {"cores": os.cpu_count(), "python": platform.python_version(),
                        "cyclonedds": _version("cyclonedds"), "platform": platform.platform()},
            "size": options.size, "width": width, "height": height, "cloud_bytes": width * height * 20,
            "cyclone": {"interface": "lo", "max_message_size": options.max_message_size or "default (14720 B)",
                        "socket_receive_buffer_min": options.receive_buffer or "default"},
            "latency": {"clouds": len(pairs), "rate_hz": options.rate, "graph": _quantiles_ms(graph_ns),
                        "dds": _quantiles_ms(dds_ns), "added": _quantiles_ms(added_ns)},
            "throughput": {"clouds": options.clouds, "window": options.window, "taken": len(taken),
                           "clouds_per_s": len(taken) / elapsed_s,
                           "mb_per_s": len(taken) * width * height * 20 / elapsed_s / 1e6,
                           "bridge_cpu_ms_per_cloud": 1e3 * cpu_bridge_s / max(len(taken), 1)},
            "intact": bench.corrupt == 0 and len(taken) == options.clouds and len(pairs) == options.clouds,
            "corrupt": bench.corrupt,
        }
        return report
    finally:
        if bench is not None:
            bench.close()
        bridge.terminate()
        try:
            bridge.wait(timeout=10)
        except subprocess.TimeoutExpired:
            bridge.kill()
        shutil.rmtree(folder, ignore_errors=True)
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _version(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "?"


def format_report(report: dict) -> str:
    lat, thr = report["latency"], report["throughput"]
    return "\n".join([
        f"dptpu bench bridge ({report['width']}x{report['height']} organized clouds, {report['cloud_bytes']:,} bytes, "
        f"cyclonedds {report['machine']['cyclonedds']} on lo, {report['machine']['cores']} cores)",
        f"(a) latency, {lat['clouds']} clouds at {lat['rate_hz']:g}/s:",
        f"    graph /scanner/points : p50 {lat['graph']['p50_ms']:7.2f} ms  p99 {lat['graph']['p99_ms']:7.2f} ms",
        f"    DDS rt/scanner/points : p50 {lat['dds']['p50_ms']:7.2f} ms  p99 {lat['dds']['p99_ms']:7.2f} ms",
        f"    added by the bridge   : p50 {lat['added']['p50_ms']:7.2f} ms  p99 {lat['added']['p99_ms']:7.2f} ms",
        f"(b) throughput, {thr['clouds']} clouds, window {thr['window']}: {thr['clouds_per_s']:.1f} clouds/s "
        f"({thr['mb_per_s']:.0f} MB/s), bridge CPU {thr['bridge_cpu_ms_per_cloud']:.1f} ms/cloud",
        f"clouds intact: {'yes' if report['intact'] else 'NO'} ({report['corrupt']} corrupt)",
    ])


def run(args) -> int:
    """The ``dptpu bench bridge`` entry: print the report; 0 when every cloud arrived intact, else 1."""
    report = measure(args)
    print(json.dumps(report, indent=2) if getattr(args, "json", False) else format_report(report))
    return 0 if report["intact"] else 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--size", choices=tuple(SIZES), default="full", help="full: 640x480 (default); small: 64x48")
    parser.add_argument("--clouds", type=int, default=None, help="clouds per measurement (default 40; small 10)")
    parser.add_argument("--rate", type=float, default=None, help="clouds/s of the latency run (default 5)")
    parser.add_argument("--window", type=int, default=None, help="clouds in flight in the throughput run (default 2)")
    parser.add_argument("--domain", type=int, default=None, help="DDS domain (default 199)")
    parser.add_argument("--max-message-size", type=int, default=None,
                        help="Cyclone MaxMessageSize in bytes (default: Cyclone's 14720)")
    parser.add_argument("--receive-buffer", default=None,
                        help="Cyclone SocketReceiveBufferSize min, e.g. 4MB (at most net.core.rmem_max; default: "
                             "Cyclone's)")


if __name__ == "__main__":
    main_parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(main_parser)
    sys.exit(run(main_parser.parse_args()))
