"""The real CFPE captures (read-only, ../shared/data/cfpe): heterodyne unwrapping of real frames.

The frames are never copied: each test writes a ``capture.yaml`` into a temporary folder whose image
lists hold the ABSOLUTE paths of the real PNGs (the format allows absolute paths; no symlinks).

What the data is, verified here against the frames (the README's description of the source code):

- ``CCII h.png``: ``II // 12`` is the sequence, projector periods 42, 45, 48 px (in that order, the
  highest frequency first: the wrapped phase gradients stand in the ratio 48 : 45 : 42);
  ``II % 12`` the step.
- The projected step is ``+2 pi s / 12``: ``phase_shift_sign: +1``. With -1 every phase is mirrored, the
  heterodyne beat tree puts ``x_p`` at ``5040 - x_p`` (3100..5000 px, off the 1920 px projector) and no
  pixel stays valid.
- Stripes are vertical (``fringe_axis: x``) and the absolute phase INCREASES with the image column:
  about 0.3 rad, i.e. ~2 projector pixels, per camera column on the board.
"""
import numpy as np
import pytest
import yaml

from dptpu.fpp.capture import load_sequence_images, read_capture
from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.reconstruct import unwrap_capture

PERIODS_PX = (42, 45, 48)
PROJECTOR_SIZE = (1920, 1080)
SCENES = ("01", "04", "06", "08")
# Regions (rows, columns) of the 480 x 640 frames, chosen on the white-reference frame ``CC36h.png``:
BOARD_BAND = (slice(30, 60), slice(20, 620))  # white board above every object, below the unlit top edge
PLATE = (slice(110, 380), slice(160, 520))  # scene 01: inside the plate's rim
BOARD_LEFT = (slice(70, 420), slice(10, 90))  # scene 01: board left of the plate


def write_cfpe_capture(cfpe_dir, scene, folder, *, phase_shift_sign=1):
    """A capture.yaml in ``folder`` that references the real frames of ``scene`` by absolute path."""
    folder.mkdir(parents=True, exist_ok=True)
    document = {
        "format": "dptpu-capture/1",
        "camera": {"size": [640, 480], "bit_depth": 8},
        "projector": {"size": list(PROJECTOR_SIZE)},
        "fringe_axis": "x",
        "phase_shift_sign": phase_shift_sign,
        "pattern": {"offset": 128 / 255, "amplitude": 96 / 255},
        "sequences": [
            {"period": period, "steps": 12,
             "images": [str((cfpe_dir / f"{scene}{12 * i + step:02d}h.png").resolve()) for step in range(12)]}
            for i, period in enumerate(PERIODS_PX)
        ],
        "references": {"white": str((cfpe_dir / f"{scene}36h.png").resolve())},
        "source": "yongleex/CFPE data/recordings/2 (MIT)",
    }
    (folder / "capture.yaml").write_text(yaml.safe_dump(document, sort_keys=False))
    return folder


@pytest.fixture(scope="module")
def heterodyne(cfpe_dir, tmp_path_factory):
    """Heterodyne result of every scene, computed once."""
    root = tmp_path_factory.mktemp("cfpe")
    return {scene: unwrap_capture(read_capture(write_cfpe_capture(cfpe_dir, scene, root / scene)),
                                  method="heterodyne")
            for scene in SCENES}


def _board_gradient(phase):
    """Median horizontal phase difference (rad per camera column) on the board band, wrapped to (-pi, pi]."""
    step = np.diff(phase[BOARD_BAND], axis=1)
    return float(np.median(np.angle(np.exp(1j * step))))


def test_sequences_are_periods_42_45_48_in_file_order(cfpe_dir, tmp_path):
    capture = read_capture(write_cfpe_capture(cfpe_dir, "01", tmp_path))
    gradients = [_board_gradient(wrapped_phase(load_sequence_images(capture, s), shift_sign=1).phase)
                 for s in capture.sequences]
    print("wrapped-phase gradients on the board (rad/column):", np.round(gradients, 4))
    assert all(g > 0 for g in gradients)  # phase increases with the image column
    # Gradient ratios are the frequency ratios, 1/42 : 1/45 : 1/48.
    assert gradients[0] / gradients[1] == pytest.approx(45 / 42, rel=0.01)
    assert gradients[0] / gradients[2] == pytest.approx(48 / 42, rel=0.01)


def test_phase_shift_sign_is_plus_one(cfpe_dir, tmp_path, heterodyne):
    wrong = unwrap_capture(read_capture(write_cfpe_capture(cfpe_dir, "01", tmp_path, phase_shift_sign=-1)),
                           method="heterodyne")
    right = heterodyne["01"]
    print(f"board valid fraction: sign +1 {right.valid[BOARD_BAND].mean():.4f}, "
          f"sign -1 {wrong.valid[BOARD_BAND].mean():.4f}")
    assert right.valid[BOARD_BAND].mean() > 0.99
    assert wrong.valid.mean() < 0.01  # mirrored phase: x_p off the projector everywhere


@pytest.mark.parametrize("scene", SCENES)
def test_every_scene_unwraps_on_the_white_board(heterodyne, scene):
    result = heterodyne[scene]
    x_p = result.absolute_phase * PROJECTOR_SIZE[0] / (2 * np.pi * result.frequency)
    board_valid = result.valid[BOARD_BAND].mean()
    print(f"scene {scene}: valid {result.valid.mean():.4f} of the frame, {board_valid:.4f} of the board band; "
          f"x_p {np.percentile(x_p[result.valid], [1, 99]).round(1)} px")
    # Measured: board band 1.0000 in every scene; whole frame 0.957, 0.955, 0.926, 0.863 (unlit borders,
    # shadows, the dark figurine's folds, the bottle's saturated print).
    assert board_valid > 0.99
    assert result.valid.mean() > 0.8
    assert result.frequency == pytest.approx(1920 / 42)
    gradient = np.median(np.diff(result.absolute_phase[BOARD_BAND], axis=1))
    assert 0.2 < gradient < 0.4  # rad per camera column: ~2 projector px per column, increasing


def test_scene01_absolute_phase_has_no_order_jumps(heterodyne):
    phase = heterodyne["01"].absolute_phase
    for name, region in (("plate", PLATE), ("board", BOARD_LEFT)):
        values = phase[region]
        assert np.isfinite(values).all(), name  # every pixel valid
        along_rows = np.diff(values, axis=1)
        along_columns = np.diff(values, axis=0)
        worst = max(np.abs(along_rows - np.median(along_rows)).max(),
                    np.abs(along_columns - np.median(along_columns)).max())
        print(f"{name}: largest neighbour-difference deviation {worst:.3f} rad")
        # Measured 0.111 (plate) and 0.053 (board); an order error would add 2 pi = 6.28.
        assert worst < 1.0


def _fit_rms(values, region, terms):
    """RMS and max |residual| of a least-squares polynomial surface over a region (rad)."""
    rows, cols = np.mgrid[region[0], region[1]].astype(np.float64)
    u, v = (cols - 320) / 320, (rows - 240) / 240  # normalized image coordinates
    basis = {"1": np.ones_like(u), "u": u, "v": v, "uu": u * u, "uv": u * v, "vv": v * v}
    design = np.stack([basis[t].ravel() for t in terms], axis=1)  # (M, terms)
    coefficients, *_ = np.linalg.lstsq(design, values.ravel(), rcond=None)
    residual = values.ravel() - design @ coefficients
    return float(np.sqrt(np.mean(residual**2))), float(np.abs(residual).max())


PLANE = ("1", "u", "v")
QUADRIC = ("1", "u", "v", "uu", "uv", "vv")


@pytest.mark.parametrize("name, region, quadric_rms_bound, quadric_max_bound", [
    # Measured: plate plane RMS 1.254 rad, quadric RMS 0.080 (max 0.397);
    #           board plane RMS 0.149 rad, quadric RMS 0.045 (max 0.163).
    # The plane is poor because phase is a projective (not linear) function of the pixel on a flat
    # surface; the quadric's remainder is the projector's nonlinearity and lens distortion.
    ("plate", PLATE, 0.15, 0.8),
    ("board", BOARD_LEFT, 0.10, 0.5),
])
def test_scene01_flat_surfaces_are_smooth(heterodyne, name, region, quadric_rms_bound, quadric_max_bound):
    values = heterodyne["01"].absolute_phase[region]
    assert np.isfinite(values).all()
    plane_rms, plane_max = _fit_rms(values, region, PLANE)
    quadric_rms, quadric_max = _fit_rms(values, region, QUADRIC)
    print(f"scene 01 {name}: plane RMS {plane_rms:.4f} rad (max {plane_max:.3f}), "
          f"quadric RMS {quadric_rms:.4f} rad (max {quadric_max:.3f})")
    assert quadric_rms < quadric_rms_bound
    assert quadric_max < quadric_max_bound  # a single-pixel order jump would leave ~2 pi here
    assert quadric_rms < plane_rms
