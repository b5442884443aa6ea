import json

from dptpu.cli.main import main


def test_bench_twin_reports_raycast_dataset_and_blender_fields(capsys):
    code = main(["bench", "twin", "--json", "--size", "80x60", "--repeats", "1", "--scenes", "1"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["size"] == [80, 60] and report["frames"] == 24
    for key in ("raycast_random_scene_0", "raycast_sphere"):
        assert report[key]["triangles"] > 0 and report[key]["total_best_s"] > 0
    assert report["raycast_sphere"]["triangles"] == 81920
    assert report["dataset"]["scenes"] == 1 and report["dataset"]["scenes_per_minute"] > 0
    assert report["blender"]["seconds_per_frame"] is None and "not requested" in report["blender"]["reason"]
