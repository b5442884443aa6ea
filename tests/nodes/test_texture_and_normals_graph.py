"""Texture and normals on a running graph: Triggers -> sim (the raycast twin with sensor noise) -> phase -> unwrap ->
cloud, all in one harness over real sockets. With 16x4, 1x4, white, black the phase node's texture (white - black) and
the cloud's ``intensity`` are the scene's albedo as the twin renders it without noise, within the sensor noise; on the
twin's standard sphere the cloud's normals are the sphere's analytic normals within one degree."""
from __future__ import annotations

import numpy as np

from dptpu.fpp.calibration import save_rig
from dptpu.messages import FringeFrame, Header, Image, PointCloud2, Time, Trigger
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.phase import PhaseNode
from dptpu.nodes.sim import SimNode
from dptpu.nodes.unwrap import UnwrapNode
from dptpu.sim.image_formation import SequenceSpec, render_frames_float
from dptpu.sim.raycast import trace
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scenes import random_scene
from tests.nodes.conftest import REPO_ROOT

RIG = str(REPO_ROOT / "launch" / "params" / "twin_rig.yaml")  # sensor noise: read 1 DN, gain 0.05 DN/e-
SIZE = "96x72"
ENTRIES = ((16.0, 4), (1.0, 4))


def _triggers(sequence_id: int) -> list[Trigger]:
    count = sum(n for _, n in ENTRIES) + 2
    out, index = [], 0
    stamp_ns = 1_700_000_000_000_000_000
    for frequency, steps in ENTRIES:
        for step in range(steps):
            out.append(Trigger(header=Header(stamp=Time.from_ns(stamp_ns + index)), sequence_id=sequence_id,
                               pattern_index=index, pattern_count=count, frequency=frequency, steps=steps, step=step))
            index += 1
    for kind in ("white", "black"):
        out.append(Trigger(header=Header(stamp=Time.from_ns(stamp_ns + index)), sequence_id=sequence_id,
                           pattern_index=index, pattern_count=count, steps=1, kind=kind))
        index += 1
    return out


def test_the_texture_is_the_twins_albedo_render_within_the_sensor_noise(tmp_path):
    rig = load_twin_rig(RIG, size=SIZE)
    rig_path = save_rig(rig, tmp_path / "rig.yaml")
    with NodeHarness() as harness:
        harness.start(SimNode, source="raycast", rig=RIG, size=SIZE, scenes="random:1",
                      sequence="16x4,1x4,white,black")
        harness.start(PhaseNode, timeout_s=5.0, projector_width=912, projector_height=1140)
        harness.start(UnwrapNode, method="mf")
        cloud_node = harness.start(CloudNode, rig=str(rig_path))
        triggers = harness.publisher(Trigger, "/projector/trigger", 100)
        frames = harness.collect(FringeFrame, "/camera/image_raw")
        textures = harness.collect(Image, "/scanner/texture")
        clouds = harness.collect(PointCloud2, "/scanner/points")
        harness.connect(timeout_s=60.0)
        assert harness.spin_until(lambda: all(sub.get_publisher_count() for sub in
                                              cloud_node._side_subscriptions.values()), timeout_s=15.0)
        for trigger in _triggers(1):
            triggers.publish(trigger)
        harness.wait(frames, 10)
        (texture_image,) = harness.wait(textures, 1)
        (cloud,) = harness.wait(clouds, 1)
    texture = texture_image.to_array().astype(np.float64)  # (H, W) DN
    # the twin's albedo render without noise: white - black before quantization (sensor noise left out)
    white, black = render_frames_float(rig, trace(rig, random_scene(rig, 1)),
                                       [SequenceSpec(kind="white"), SequenceSpec(kind="black")], effects=[])
    expected = white[0] - black[0]
    assert expected.max() > 100 and np.ptp(expected[expected > 20]) > 50  # a lit scene with texture (albedo)
    # noise of white - black: read noise 1 DN and shot noise 0.05 * signal DN^2 in each frame, quantization 1/12
    # pixels the white frame does not saturate (8-bit: 255 DN)
    sigma = np.sqrt(2 * 1.0 + 0.05 * (white[0] + black[0]) + 2 / 12)
    unsaturated = white[0] + 4 * sigma < 255
    residual = (texture - expected)[unsaturated]
    sigma = sigma[unsaturated]
    # measured: median -0.22 DN (the black frame's noise is clipped at 0 DN), RMS 2.97 DN against the model's
    # 3.07 DN, over 99 % of the pixels
    assert abs(np.median(residual)) < 0.5  # no bias
    assert 0.8 < np.sqrt(np.mean(residual**2)) / np.sqrt(np.mean(sigma**2)) < 1.2  # the noise, no more
    intensity = cloud.to_array(["intensity"])[..., 0]
    published = np.isfinite(cloud.to_array(["z"])[..., 0])
    assert published.sum() > 0.3 * published.size
    assert np.array_equal(intensity[published], texture_image.to_array()[published])  # the cloud carries it


def _fringe_triggers(sequence_id: int, entries) -> list[Trigger]:
    count = sum(n for _, n in entries)
    out, index = [], 0
    for frequency, steps in entries:
        for step in range(steps):
            out.append(Trigger(header=Header(stamp=Time.from_ns(1_700_000_000_000_000_000 + index)),
                               sequence_id=sequence_id, pattern_index=index, pattern_count=count, frequency=frequency,
                               steps=steps, step=step))
            index += 1
    return out


def test_the_normals_of_the_twins_sphere_are_its_analytic_normals_within_one_degree(tmp_path):
    """The standard 50.8 mm sphere at 800 mm, 320x240 (the main job's size, 0.6 mm between pixels there), 64x12 and
    1x12 MF with sensor noise: each cloud normal against the normal of the sphere fitted to the cloud's points
    (``(P - c) / |P - c|``). The noise of one central difference is several degrees here (0.09 mm of depth noise
    over 1.2 mm), so the test asks the node for 7 x 7 windows: measured median 0.78 deg, 90th percentile 2.4 deg
    (the silhouette, where the surface turns away); 3 x 3 (the default): 1.74 / 3.6 deg, 5 x 5: 0.98 / 2.2 deg."""
    from dptpu.fpp.fitting import fit_sphere

    size = "320x240"
    rig_path = save_rig(load_twin_rig(RIG, size=size), tmp_path / "rig.yaml")
    with NodeHarness() as harness:
        harness.start(SimNode, source="raycast", rig=RIG, size=size, scenes="sphere", sequence="64x12,1x12")
        harness.start(PhaseNode, timeout_s=5.0, projector_width=912, projector_height=1140)
        harness.start(UnwrapNode, method="mf")
        harness.start(CloudNode, rig=str(rig_path), normal_window_px=7)
        triggers = harness.publisher(Trigger, "/projector/trigger", 100)
        clouds = harness.collect(PointCloud2, "/scanner/points")
        harness.connect(timeout_s=60.0)
        for trigger in _fringe_triggers(1, ((64.0, 12), (1.0, 12))):
            triggers.publish(trigger)
        (cloud,) = harness.wait(clouds, 1)
    xyz = cloud.to_array(["x", "y", "z"]).astype(np.float64)  # (H, W, 3) metres
    published = np.isfinite(xyz[..., 2])
    fit = fit_sphere(xyz[published])
    assert abs(fit.radius - 0.0254) < 0.0001 and published.sum() > 4000  # the standard sphere, 5,012 points
    truth = xyz[published] - fit.center
    truth /= np.linalg.norm(truth, axis=-1, keepdims=True)  # outward: toward the camera on the visible side
    normals = cloud.to_array(["normal_x", "normal_y", "normal_z"]).astype(np.float64)[published]
    angle_deg = np.degrees(np.arccos(np.clip(np.sum(normals * truth, axis=-1), -1.0, 1.0)))
    assert np.isfinite(angle_deg).all()
    assert np.median(angle_deg) < 1.0 and np.percentile(angle_deg, 90) < 3.0
