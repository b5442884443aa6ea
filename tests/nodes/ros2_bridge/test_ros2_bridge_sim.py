"""The bridge during a sim-mode run: ``launch/sim_rig.yaml`` (160x120) scans the twin's scenes, and a Cyclone DDS
subscriber in another process, with ROS 2's IDL types of its own, receives ``rt/scanner/points``.

Each cloud taken over DDS is matched by its stamp to the cloud the graph itself published on ``/scanner/points``
(heard by the test's probe) and must equal it exactly: header, field names, offsets, datatypes, steps, every
byte of the points, so the same coordinates and the same count of finite points.
"""
from __future__ import annotations

import numpy as np

from dptpu.messages import PointCloud2
from tests.launch_files.running import SIM_RIG, TWIN_RIG_ARG, LaunchRun
from tests.nodes.ros2_bridge.test_ros2_bridge import assert_same_cloud, dds_env, start_bridge, start_subscriber, stop

CLOUDS = 2


def test_ros2_subscriber_receives_the_sim_rig_clouds_exactly(node_env, probe, tmp_path):
    env = dds_env(node_env)
    graph_clouds = probe.subscribe(PointCloud2, "/scanner/points", 20)
    bridge = start_bridge(env)
    listener = start_subscriber(tmp_path, env, clouds=CLOUDS)
    listener.wait_event("ready", timeout=30)
    run = LaunchRun(SIM_RIG, "scans:=0", TWIN_RIG_ARG, "size:=160x120", "sequence:=16x4,1x4", "method:=mf", "ply_dir:=",
                    "frame_rate:=40.0", env=env, cwd=tmp_path)
    try:
        events = [run_event(listener, run) for _ in range(CLOUDS)]
        for event in events:
            stamp = tuple(event["stamp"])
            cloud = graph_clouds.wait_for(
                lambda c, stamp=stamp: (c.header.stamp.sec, c.header.stamp.nanosec) == stamp, 10)
            assert (cloud.width, cloud.height) == (160, 120)
            assert int(np.isfinite(cloud.to_array(["z"])).sum()) > 500  # the scene is in view
            assert_same_cloud(event, cloud)
        assert [f[0] for f in events[0]["fields"]] == [
            "x", "y", "z", "intensity", "modulation", "confidence", "normal_x", "normal_y", "normal_z"]
    finally:
        run.close()
        stop(listener, bridge)


def run_event(listener, run) -> dict:
    """The listener's next cloud; on a timeout the launch's output is in the message."""
    try:
        return listener.wait_event("cloud", timeout=60)
    except AssertionError as exc:
        raise AssertionError(f"{exc}\nlaunch output:\n{run.text()}") from None
