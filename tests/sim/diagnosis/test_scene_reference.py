"""``--reference scene:FILE``: the scene's pose registered from the measured data (ICP), then the diagnosis as
for a sphere or a plane; and what self-reference cannot show is reported, not skipped."""
import numpy as np
import pytest
import yaml

from dptpu.cli.main import main
from dptpu.sim.diagnosis import diagnose
from dptpu.sim.diagnosis.reference import Reference, load_scene_reference, posed_meshes
from dptpu.sim.diagnosis.report import write_report
from dptpu.sim.render import render_capture
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scenes.scene import Scene, euler_xyz_deg

from .hidden import SEQUENCES, SIZE, render_measured

#: A bumpy blob in front of a wall: the blob pins all six degrees of freedom, the wall is most of the image.
SCENE = {"name": "blob-on-wall", "objects": [
    {"name": "blob", "shape": "blob", "radius": 30, "amplitude": 0.25, "seed": 4, "frame": "working"},
    {"name": "wall", "shape": "plane", "size": [300, 240], "frame": "working", "pose": {"translation": [0, 0, 50]}},
]}
#: The "measured" scene: the file's scene turned by ~1.1 deg about its centroid and moved by a few mm.
TRUE_ROTATION_DEG = (0.6, -0.8, 0.5)
TRUE_SHIFT_MM = np.array([2.0, -1.5, 3.0])


@pytest.fixture(scope="module")
def moved_scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("scene")
    path = root / "scene.yaml"
    path.write_text(yaml.safe_dump(SCENE))
    rig = load_twin_rig("nominal", size=SIZE)
    reference = load_scene_reference(Reference("scene", path=str(path)), rig)
    centroid = np.vstack([m.vertices for m in reference.scene.meshes]).mean(axis=0)
    rotation = euler_xyz_deg(TRUE_ROTATION_DEG)
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = centroid + TRUE_SHIFT_MM - rotation @ centroid
    folder = root / "measured"
    render_capture(rig, Scene(meshes=list(posed_meshes(reference, pose)), name="moved"), list(SEQUENCES), folder,
                   effects=[{"projector_gamma": {"gamma": 1.5}}], seed=1)
    result = diagnose(folder, rig, reference=f"scene:{path}", max_pixels=1000)
    return result, reference, pose, root


def test_scene_pose_offset_is_registered(moved_scene):
    result, reference, true_pose, _ = moved_scene
    registration = result.registration
    change = registration.pose_change
    # the centroid's displacement within 10 um, the rotation within 0.05 deg (ICP on noiseless 8-bit data:
    # 3 um and 0.04 deg)
    np.testing.assert_allclose(change["centroid_translation"], TRUE_SHIFT_MM, atol=0.01)
    true_angle = np.degrees(np.arccos((np.trace(true_pose[:3, :3]) - 1) / 2))
    assert abs(change["rotation_deg"] - true_angle) < 0.05
    # the blob (what pins the pose) lands within 50 um everywhere
    blob = reference.scene.meshes[0].vertices
    fitted = blob @ registration.pose[:3, :3].T + registration.pose[:3, 3]
    truth = blob @ true_pose[:3, :3].T + true_pose[:3, 3]
    assert np.linalg.norm(fitted - truth, axis=1).max() < 0.05
    # the traced twin at the registered pose explains the measured coordinate to 0.01 projector px
    assert registration.rms_px < 0.01
    assert registration.order_errors == 0.0


def test_scene_reference_continues_as_for_a_sphere(moved_scene):
    result, _, _, root = moved_scene
    assert result.cause == "projector_gamma"
    assert abs(result.effects[0]["parameters"]["gamma"] - 1.5) < 0.1
    report = write_report(result, root / "out")
    assert report["reference"].startswith("scene:")
    assert report["registration"]["pose_change"]["rotation_deg"] > 0.5
    assert "Scene pose change" in (root / "out" / "report.md").read_text()
    again = report["rerender"]["intensity_rms_dn"]
    assert again["extended_twin"] < 0.2 * again["twin"]


@pytest.mark.parametrize("write, message", [
    (None, "no such scene file"),
    ("objects: [{shape: cone}]", "objects[0].shape: must be one of"),
])
def test_bad_scene_file_exits_2_naming_it(tmp_path, capsys, write, message):
    path = tmp_path / "bad.yaml"
    if write is not None:
        path.write_text(write)
    folder, _ = render_measured(tmp_path / "measured", "plane")
    code = main(["twin", "diagnose", "--measured", str(folder), "--rig", "nominal", "--reference",
                 f"scene:{path}", "--out", str(tmp_path / "out")])
    assert code == 2
    error = capsys.readouterr().err
    assert message in error and "bad.yaml" in error


def test_self_reference_reports_what_it_cannot_show(tmp_path):
    folder, _ = render_measured(tmp_path / "measured", "plane", {"projector_gamma": {"gamma": 1.6}})
    result = diagnose(folder, None, self_reference=True, max_pixels=1000)
    assert result.cause == "projector_gamma"
    silent = {e["name"]: e for e in result.effects if e["evidence"].get("identifiable") is False}
    assert set(silent) == {"projector_pixelation", "vignetting", "camera_defocus", "motion"}
    for entry in silent.values():
        assert not entry["named"] and len(entry["evidence"]["reason"]) > 40
