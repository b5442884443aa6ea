"""The sim rig runs inside a namespace: a ROS 2 launch file of one's own that includes it under
``push_ros_namespace`` (a second scanner on one robot) scans, as at the root.

Before: the shipped parameter files named their nodes without a namespace (``projector:``), so ``/robot1/projector``
opened /dev/ttyACM0 instead of the emulator, and the scan monitor called ``/projector/start_scan``, which no node
served, so no scan ever started and nothing said why.
"""
from __future__ import annotations

from tests.launch_files.running import LaunchRun

WRAPPER = """\
launch:
  - arg: {name: algo, default: mf, choice: [{value: mf}, {value: nt}]}
  - let: {name: twin, value: $(find-pkg-share dptpu)/launch/params/twin_rig.yaml}
  - group:
      - push_ros_namespace: {namespace: /robot1}
      - include:
          file: $(find-pkg-share dptpu)/launch/sim_rig.yaml
          arg:
            - {name: scans, value: "2"}
            - {name: method, value: $(var algo)}
            - {name: rig, value: $(var twin)}
            - {name: size, value: 160x120}
            - {name: sequence, value: "16x4,1x4"}
            - {name: scenes, value: "sphere,plane"}
            - {name: ply_dir, value: ""}
"""


def test_sim_rig_included_under_a_namespace_scans(node_env, tmp_path):
    wrapper = tmp_path / "robot1.yaml"
    wrapper.write_text(WRAPPER)
    run = LaunchRun(wrapper, env=node_env, cwd=tmp_path)
    try:
        code = run.wait(timeout=180)
    finally:
        run.close()
    scans = run.scans()
    assert code == 0, run.text()
    assert [outcome for _, _, outcome, _ in scans] == ["ok", "ok"], run.text()
    assert "/dev/tty" not in run.text(200)  # the projector got its emulator port from params/projector_sim.yaml

