"""The one point-cloud writer: metres by default, every field the cloud has (normals, intensity, modulation,
confidence) under its name in PLY and PCD, read back by open3d."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.point_cloud_file import write_point_cloud


def _organized(rng):
    points = rng.uniform(-200.0, 200.0, (4, 5, 3))  # (H, W, 3) mm
    points[0, 0] = np.nan  # a pixel without a point
    normals = rng.normal(size=(4, 5, 3))
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    fields = {"intensity": rng.uniform(0, 255, (4, 5)), "modulation": rng.uniform(0, 100, (4, 5)),
              "confidence": rng.uniform(0, 1, (4, 5))}
    return points, normals, fields


@pytest.mark.parametrize("suffix", [".ply", ".pcd"])
def test_normals_and_named_fields_are_written_per_finite_point_in_metres(tmp_path, suffix):
    import open3d as o3d

    points, normals, fields = _organized(np.random.default_rng(0))
    path = tmp_path / f"cloud{suffix}"
    assert write_point_cloud(path, points, unit="mm", intensity=fields["intensity"], normals=normals,
                             fields=fields) == 19
    read = o3d.t.io.read_point_cloud(str(path)).point
    kept = np.isfinite(points).all(axis=-1)
    np.testing.assert_allclose(read.positions.numpy(), points[kept] / 1000.0, rtol=1e-12)  # metres
    np.testing.assert_allclose(read.normals.numpy(), normals[kept], atol=1e-12)  # not scaled
    for name, values in fields.items():
        np.testing.assert_allclose(read[name].numpy()[:, 0], values[kept], rtol=1e-6)
    legacy = o3d.io.read_point_cloud(str(path))  # the grey colours of the intensity, as before
    grey = np.clip(fields["intensity"][kept] / np.percentile(fields["intensity"][kept], 99), 0, 1)
    np.testing.assert_allclose(np.asarray(legacy.colors)[:, 0], np.round(grey * 255) / 255, atol=1e-9)


def test_millimetres_on_request_and_bad_fields_refused(tmp_path):
    import open3d as o3d

    points, normals, fields = _organized(np.random.default_rng(1))
    write_point_cloud(tmp_path / "mm.ply", points, unit="mm", file_unit="mm",
                      fields={"confidence": fields["confidence"]})
    kept = np.isfinite(points).all(axis=-1)
    np.testing.assert_allclose(o3d.t.io.read_point_cloud(str(tmp_path / "mm.ply")).point.positions.numpy(),
                               points[kept], rtol=1e-12)
    with pytest.raises(ValueError, match="field name 'normals' must be an identifier other than"):
        write_point_cloud(tmp_path / "a.ply", points, unit="m", fields={"normals": fields["confidence"]})
    with pytest.raises(ValueError, match=r"field confidence must have the shape \(4, 5\) of the points; got \(20,\)"):
        write_point_cloud(tmp_path / "a.ply", points, unit="m", fields={"confidence": np.zeros(20)})
    with pytest.raises(ValueError, match=r"a.xyz: normals and fields are written to .ply and .pcd files only"):
        write_point_cloud(tmp_path / "a.xyz", points, unit="m", normals=normals)
