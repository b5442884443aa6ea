"""A small in-process harness to test node logic: real nodes, real ZeroMQ sockets, one process, no threads.

The node under test and a *probe* node (the harness's publishers and collectors) live in one private
:class:`dptpu.graph.Context`; one :class:`~dptpu.graph.SingleThreadedExecutor` runs both in the calling
thread, only while the test waits (:meth:`NodeHarness.spin_until`). Messages therefore go through the
same encode, socket, decode path as between processes, and a callback's exception fails the test instead
of being logged (``raise_callback_exceptions=True``).

```python
from dptpu.messages import FringeFrame, PhaseMaps
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode

with NodeHarness() as harness:
    node = harness.start(PhaseNode, timeout_s=0.5)             # parameters as keyword arguments
    camera = harness.publisher(FringeFrame, "/camera/image_raw")
    phase = harness.collect(PhaseMaps, "/scanner/phase")
    harness.connect()                                           # wait until every pair is connected
    for frame in fringe_frames([stack_16, stack_1], [16.0, 1.0], sequence_id=7):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)                            # spins until one PhaseMaps arrived
```

Isolation: by default the harness points ``DPTPU_DISCOVERY_DIR`` at a fresh folder under ``/tmp`` for its
lifetime (restored and removed on exit), so it never meets another test's nodes or a real graph. That
variable is process-wide: do not start other graph contexts in other threads meanwhile.
"""
from __future__ import annotations

import os
import shutil
import tempfile
import threading
import time

import numpy as np

from dptpu.graph import Context, Parameter, SingleThreadedExecutor
from dptpu.graph.node import Node
from dptpu.graph.qos import QoSProfile
from dptpu.graph.subscription import Subscription
from dptpu.messages import FringeFrame, Header, Image, Time, Trigger
from dptpu.nodes.plumbing import DEFAULT_FRAME_ID

__all__ = ["NodeHarness", "Collector", "fringe_frames"]

_DEFAULT_DOMAIN_ID = 42


class Collector:
    """Messages received on one topic, in arrival order (``messages``); ``len()`` counts them."""

    def __init__(self, topic: str):
        self.topic = topic
        self.messages: list = []
        self.subscription: Subscription | None = None  # set by NodeHarness.collect
        self._lock = threading.Lock()

    def __call__(self, msg) -> None:
        with self._lock:
            self.messages.append(msg)

    def __len__(self) -> int:
        return len(self.messages)

    def clear(self) -> None:
        with self._lock:
            self.messages.clear()


class NodeHarness:
    """Run nodes in this process on a private domain; publish their inputs, collect their outputs.

    Parameters
    ----------
    domain_id : int
        Domain of the harness's context.
    private : bool
        Point ``DPTPU_DISCOVERY_DIR`` at a fresh temporary folder while the harness is open (default).
        False: use the environment as it is (e.g. a test fixture already made it private).
    """

    def __init__(self, *, domain_id: int = _DEFAULT_DOMAIN_ID, private: bool = True):
        self.domain_id = domain_id
        self.private = private
        self.context: Context | None = None
        self.executor: SingleThreadedExecutor | None = None
        self.probe: Node | None = None
        self.nodes: list = []
        self._inputs: list = []
        self._collectors: list[Collector] = []
        self._folder: str | None = None
        self._saved_env: str | None = None

    # -- lifecycle --------------------------------------------------------------------------------------

    def __enter__(self) -> NodeHarness:
        if self.private:
            self._folder = tempfile.mkdtemp(prefix="dh", dir="/tmp")  # short: ipc socket paths must fit
            self._saved_env = os.environ.get("DPTPU_DISCOVERY_DIR")
            os.environ["DPTPU_DISCOVERY_DIR"] = self._folder
        self.context = Context()
        self.context.init([], domain_id=self.domain_id)
        self.executor = SingleThreadedExecutor(context=self.context, raise_callback_exceptions=True)
        self.probe = Node("harness_probe", context=self.context, start_parameter_services=False)
        self.executor.add_node(self.probe)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Shut the context down (destroying every node) and restore the environment."""
        if self.context is not None:
            if self.executor is not None:
                self.executor.shutdown(timeout_sec=1.0)
            self.context.try_shutdown()
            self.context = None
        if self.private and self._folder is not None:
            if self._saved_env is None:
                os.environ.pop("DPTPU_DISCOVERY_DIR", None)
            else:
                os.environ["DPTPU_DISCOVERY_DIR"] = self._saved_env
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None

    def _running(self) -> tuple[SingleThreadedExecutor, Node]:
        """The executor and the probe node, which exist inside the ``with`` block."""
        if self.executor is None or self.probe is None:
            raise RuntimeError("the harness is not running: use it as `with NodeHarness() as harness:`")
        return self.executor, self.probe

    # -- wiring -----------------------------------------------------------------------------------------

    def start(self, node_class, *, cli_args=None, **parameters):
        """Create ``node_class(context=..., parameter_overrides=...)`` in the harness and spin it with the probe.

        Keyword arguments are parameter values (``timeout_s=0.5``; a DOUBLE parameter needs a float).
        """
        executor, _ = self._running()
        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        node = node_class(context=self.context, cli_args=cli_args, parameter_overrides=overrides)
        self.nodes.append(node)
        executor.add_node(node)
        return node

    def publisher(self, msg_type, topic: str, qos=10, *, connect: bool = True):
        """A probe publisher; :meth:`connect` waits for a subscriber on it unless ``connect=False``."""
        _, probe = self._running()
        publisher = probe.create_publisher(msg_type, topic, qos)
        if connect:
            self._inputs.append(publisher)
        return publisher

    def collect(self, msg_type, topic: str, qos=None) -> Collector:
        """A probe subscription that keeps every message of ``topic`` (default QoS: reliable, depth 1000)."""
        _, probe = self._running()
        collector = Collector(topic)
        collector.subscription = probe.create_subscription(msg_type, topic, collector,
                                                           qos if qos is not None else QoSProfile(depth=1000))
        self._collectors.append(collector)
        return collector

    def connect(self, timeout_s: float = 15.0) -> None:
        """Wait until every probe publisher has a subscriber and every collector a publisher.

        Raises
        ------
        TimeoutError
            Naming the topics still unconnected (a typo in a topic name, or incompatible QoS).
        """
        def missing():
            return ([p.topic_name for p in self._inputs if p.get_subscription_count() < 1]
                    + [c.topic for c in self._collectors
                       if c.subscription is None or c.subscription.get_publisher_count() < 1])

        if not self.spin_until(lambda: not missing(), timeout_s):
            raise TimeoutError(f"not connected within {timeout_s} s: {', '.join(missing())}")

    # -- running ----------------------------------------------------------------------------------------

    def spin_until(self, predicate, timeout_s: float = 5.0) -> bool:
        """Run callbacks until ``predicate()`` is true (True) or ``timeout_s`` passed (False)."""
        executor, _ = self._running()
        deadline = time.monotonic() + timeout_s
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            executor.spin_once(timeout_sec=min(0.02, remaining))
        return True

    def spin_for(self, seconds: float) -> None:
        """Run callbacks (messages, timers) for ``seconds``."""
        self.spin_until(lambda: False, seconds)

    def wait(self, collector: Collector, count: int = 1, timeout_s: float = 30.0) -> list:
        """The first ``count`` messages of ``collector``, spinning until they arrived.

        Raises
        ------
        TimeoutError
            When fewer arrived in time (the message says how many).
        """
        if not self.spin_until(lambda: len(collector) >= count, timeout_s):
            raise TimeoutError(f"{collector.topic}: {len(collector)} of {count} messages within {timeout_s} s")
        return list(collector.messages[:count])


#: The exposure start of scan 0's first frame in :func:`fringe_frames`; scan ``s`` starts ``s`` seconds later.
FIRST_STAMP_NS = 1_700_000_000_000_000_000


def fringe_frames(stacks, frequencies, *, sequence_id: int, stamp_ns: int | None = None,
                  frame_period_ns: int = 1_333_333, frame_id: str = DEFAULT_FRAME_ID) -> list:
    """The FringeFrames of one scan, in projection order, as a camera publishes them.

    Parameters
    ----------
    stacks : sequence of ndarray (N_e, H, W) uint8 or uint16
        Camera frames of each entry, step order.
    frequencies : sequence of float
        Periods across the projector extent, one per entry.
    sequence_id : int
        The scan.
    stamp_ns, frame_period_ns : int
        Exposure start of the first frame and the time between frames (default 750 frames/s). Default stamp:
        :data:`FIRST_STAMP_NS` plus ``sequence_id`` seconds, so two scans never share a stamp (the cloud node
        matches a scan's texture and modulation images to it by stamp, as a ROS 2 synchronizer does: two scans of
        one stamp would take each other's images).

    Returns
    -------
    list of FringeFrame
        ``sum(N_e)`` frames; ``trigger.pattern_index`` counts over all entries, ``pattern_count`` is the
        total.
    """
    if len(stacks) != len(frequencies):
        raise ValueError(f"one frequency per stack; got {len(stacks)} stacks and {len(frequencies)} frequencies")
    count = sum(int(np.shape(stack)[0]) for stack in stacks)
    if stamp_ns is None:
        stamp_ns = FIRST_STAMP_NS + int(sequence_id) * 1_000_000_000
    frames, index = [], 0
    for stack, frequency in zip(stacks, frequencies):
        steps = int(np.shape(stack)[0])
        for step in range(steps):
            header = Header(stamp=Time.from_ns(stamp_ns + index * frame_period_ns), frame_id=frame_id)
            trigger = Trigger(header=header, sequence_id=sequence_id, pattern_index=index, pattern_count=count,
                              frequency=float(frequency), steps=steps, step=step)
            frames.append(FringeFrame(image=Image.from_array(np.ascontiguousarray(stack[step]), header=header),
                                      trigger=trigger))
            index += 1
    return frames
