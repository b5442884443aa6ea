"""The scanner's processes, one subpackage each: ``projector``, ``camera``, ``sim``, ``phase``, ``unwrap``, ``cloud``,
``scan_monitor``, ``ros2_bridge``, ``viewer``.

Each runs as ``python -m dptpu.nodes.NAME`` (or ``pkg: dptpu, exec: NAME`` in a launch file) and exports its node
class and ``main`` (``from dptpu.nodes.phase import PhaseNode, main``); a helper used by one node lives in that
node's package. What several nodes share lives here: :mod:`.node_main` (the ``main()`` of every node),
:mod:`.plumbing` (QoS, the default frame, ScanStatus reports, back-off) and :mod:`.harness` (``NodeHarness``, the
in-process test bench). The measurement science is :mod:`dptpu.fpp`; a node feeds it and publishes.
"""
