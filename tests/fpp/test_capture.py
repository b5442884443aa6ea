"""Capture folders (dptpu-capture/1): round trip, frequency accessor, and every kind of bad input."""
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from dptpu.fpp.capture import (
    CAPTURE_FILE,
    GraycodeFrames,
    GraycodeSequence,
    PatternLevels,
    PhaseFrames,
    PhaseSequence,
    load_ground_truth,
    load_image,
    load_images,
    load_reference,
    load_sequence_images,
    read_capture,
    write_capture,
    write_capture_yaml,
)

SHAPE = (24, 32)  # (H, W); camera.size is [32, 24]


def _stack(n, rng, dtype=np.uint8):
    high = 255 if dtype == np.uint8 else 4095
    return rng.integers(0, high + 1, size=(n,) + SHAPE).astype(dtype)


def _write_small(folder, *, dtype=np.uint8, **options):
    rng = np.random.default_rng(0)
    sequences = [PhaseFrames(images=_stack(12, rng, dtype), frequency=96),
                 PhaseFrames(images=_stack(4, rng, dtype), period=60.0, phase_offset=0.25)]
    return write_capture(folder, sequences=sequences, projector_size=(912, 1140), **options), sequences


def _edit_yaml(folder: Path, edit) -> None:
    path = folder / CAPTURE_FILE
    document = yaml.safe_load(path.read_text())
    edit(document)
    path.write_text(yaml.safe_dump(document, sort_keys=False))


# --------------------------------------------------------------------------------------------------
# Round trip
# --------------------------------------------------------------------------------------------------

def test_write_then_read_round_trips_every_field(tmp_path):
    rng = np.random.default_rng(0)
    high = PhaseFrames(images=_stack(12, rng), frequency=96)
    low = PhaseFrames(images=_stack(3, rng), period=9.5, phase_offset=0.5)
    code = GraycodeFrames(images=_stack(7, rng), period=9.5, inverse=_stack(7, rng),
                          complementary=_stack(1, rng)[0], complementary_inverse=_stack(1, rng)[0])
    white, black = _stack(1, rng)[0], _stack(1, rng)[0]
    projector_x = rng.random(SHAPE).astype(np.float32) * 900
    valid = rng.random(SHAPE) > 0.3
    rig = tmp_path / "rig.yaml"
    rig.write_text("format: dptpu-rig/1\n")  # copied as is; read_capture only checks it exists
    written = write_capture(
        tmp_path / "cap", sequences=[high, low, code], projector_size=(912, 1140), fringe_axis="y",
        phase_shift_sign=1, pattern=PatternLevels(offset=0.5, amplitude=0.4),
        references={"white": white, "black": black}, calibration=rig,
        ground_truth={"projector_x": projector_x, "valid": valid}, extras={"scene": "test", "exposure_us": 800},
    )

    capture = read_capture(tmp_path / "cap" / CAPTURE_FILE)  # the yaml path works as well as the folder

    assert capture == written
    assert capture.root == (tmp_path / "cap").resolve()
    assert capture.camera_size == (32, 24) and capture.image_shape == (24, 32)
    assert capture.bit_depth == 8 and capture.projector_size == (912, 1140)
    assert capture.fringe_axis == "y" and capture.phase_shift_sign == 1
    assert capture.pattern == PatternLevels(offset=0.5, amplitude=0.4)
    assert capture.extras == {"scene": "test", "exposure_us": 800}
    assert capture.calibration.read_text() == "format: dptpu-rig/1\n"
    seq_high, seq_low, seq_code = capture.sequences
    assert isinstance(seq_high, PhaseSequence) and isinstance(seq_code, GraycodeSequence)
    assert (seq_high.frequency, seq_high.period, seq_high.steps, seq_high.phase_offset) == (96.0, None, 12, 0.0)
    assert (seq_low.frequency, seq_low.period, seq_low.steps, seq_low.phase_offset) == (None, 9.5, 3, 0.5)
    assert (seq_code.bits, seq_code.period) == (7, 9.5)
    np.testing.assert_array_equal(load_sequence_images(capture, seq_high), high.images)
    np.testing.assert_array_equal(load_sequence_images(capture, seq_low), low.images)
    np.testing.assert_array_equal(load_sequence_images(capture, seq_code), code.images)
    np.testing.assert_array_equal(load_images(capture, seq_code.inverse), code.inverse)
    np.testing.assert_array_equal(load_image(capture, seq_code.complementary), code.complementary)
    np.testing.assert_array_equal(load_image(capture, seq_code.complementary_inverse), code.complementary_inverse)
    np.testing.assert_array_equal(load_reference(capture, "white"), white)
    np.testing.assert_array_equal(load_reference(capture, "black"), black)
    truth = load_ground_truth(capture)
    np.testing.assert_array_equal(truth.projector_x, projector_x)
    np.testing.assert_array_equal(truth.valid, valid)


def test_sixteen_bit_frames_round_trip(tmp_path):
    capture, sequences = _write_small(tmp_path / "cap", dtype=np.uint16)
    assert read_capture(tmp_path / "cap").bit_depth == 16
    images = load_sequence_images(capture, capture.sequences[0])
    assert images.dtype == np.uint16
    np.testing.assert_array_equal(images, sequences[0].images)


def test_write_capture_yaml_elsewhere_references_frames_by_absolute_path(tmp_path):
    capture, _ = _write_small(tmp_path / "cap", extras={"note": "kept"})
    yaml_path = write_capture_yaml(capture, tmp_path / "elsewhere")

    document = yaml.safe_load(yaml_path.read_text())
    first = document["sequences"][0]["images"][0]
    assert Path(first).is_absolute() and Path(first).parent == (tmp_path / "cap").resolve()
    again = read_capture(tmp_path / "elsewhere")
    assert again.sequences == capture.sequences
    assert again.extras == {"note": "kept"}
    assert again.root == (tmp_path / "elsewhere").resolve()


def test_unknown_keys_are_kept_as_extras(tmp_path):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: (d.update(operator="ada"), d["sequences"][0].update(name="fine")))
    capture = read_capture(tmp_path)
    assert capture.extras == {"operator": "ada"}
    assert capture.sequences[0].extras == {"name": "fine"}


@pytest.mark.parametrize("axis, expected", [("x", 1920 / 42), ("y", 1080 / 42)])
def test_frequency_is_derived_from_period_and_the_extent_along_the_fringe_axis(tmp_path, axis, expected):
    rng = np.random.default_rng(0)
    capture = write_capture(tmp_path, sequences=[PhaseFrames(images=_stack(3, rng), period=42)],
                            projector_size=(1920, 1080), fringe_axis=axis)
    sequence = capture.sequences[0]
    assert sequence.frequency is None
    assert capture.frequency_of(sequence) == pytest.approx(expected, rel=1e-12)
    assert capture.fringe_extent_px == (1920 if axis == "x" else 1080)
    assert sequence.frequency_for(912) == pytest.approx(912 / 42, rel=1e-12)


def test_a_declared_frequency_is_used_as_is(tmp_path):
    capture, _ = _write_small(tmp_path)
    assert capture.frequency_of(capture.sequences[0]) == 96.0
    assert capture.frequency_of(capture.sequences[1]) == pytest.approx(912 / 60)


# --------------------------------------------------------------------------------------------------
# Bad capture.yaml
# --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("dotted", [
    "format", "camera", "camera.size", "camera.bit_depth", "projector", "projector.size", "fringe_axis",
    "phase_shift_sign", "sequences",
])
def test_missing_required_key_names_the_file_and_the_key(tmp_path, dotted):
    _write_small(tmp_path)

    def drop(document):
        *parents, last = dotted.split(".")
        node = document
        for key in parents:
            node = node[key]
        del node[last]

    _edit_yaml(tmp_path, drop)
    with pytest.raises(ValueError, match=rf"capture\.yaml: missing key '{dotted}'"):
        read_capture(tmp_path)


@pytest.mark.parametrize("key", ["steps", "images"])
def test_missing_sequence_key_names_the_sequence(tmp_path, key):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][1].pop(key))
    with pytest.raises(ValueError, match=rf"capture\.yaml: missing key 'sequences\[1\]\.{key}'"):
        read_capture(tmp_path)


def test_image_count_not_matching_steps(tmp_path):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][0]["images"].pop())
    with pytest.raises(ValueError, match=r"sequence 0 \(frequency 96\): 11 images listed but steps is 12"):
        read_capture(tmp_path)


@pytest.mark.parametrize("value", [0, -3.5])
def test_frequency_not_positive(tmp_path, value):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][0].update(frequency=value))
    with pytest.raises(ValueError, match=rf"sequences\[0\]\.frequency must be > 0; got {value}"):
        read_capture(tmp_path)


def test_period_not_positive(tmp_path):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][1].update(period=0))
    with pytest.raises(ValueError, match=r"sequences\[1\]\.period must be > 0; got 0"):
        read_capture(tmp_path)


@pytest.mark.parametrize("edit, word", [
    (lambda s: s.update(period=10.0), "both"),
    (lambda s: s.pop("frequency"), "neither"),
])
def test_frequency_and_period_exactly_one(tmp_path, edit, word):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: edit(d["sequences"][0]))
    with pytest.raises(ValueError, match=rf"sequences\[0\]: give exactly one of 'frequency' and 'period'; got {word}"):
        read_capture(tmp_path)


@pytest.mark.parametrize("key, value, message", [
    ("format", "dptpu-capture/2", r"format must be 'dptpu-capture/1'; got 'dptpu-capture/2'"),
    ("fringe_axis", "z", r"fringe_axis must be 'x' \(vertical stripes\) or 'y'; got 'z'"),
    ("phase_shift_sign", 0, r"phase_shift_sign must be -1 \(the paper's Eq. 1\) or \+1; got 0"),
    ("camera", {"size": [32, 24], "bit_depth": 12}, r"camera.bit_depth must be 8 or 16; got 12"),
    ("projector", {"size": [912]}, r"projector.size must be \[width, height\] in pixels"),
    ("sequences", [], r"sequences must be a non-empty list"),
    ("references", {"grey": "a.png"}, r"references may hold 'white' and 'black'; got unknown key 'grey'"),
    ("pattern", {"offset": 0.5, "amplitude": 0.6}, r"pattern offset \+- amplitude must stay within \[0, 1\]"),
])
def test_bad_values_are_named(tmp_path, key, value, message):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d.update({key: value}))
    with pytest.raises(ValueError, match=r"capture\.yaml: " + message):
        read_capture(tmp_path)


def test_steps_below_three(tmp_path):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][1].update(steps=2, images=d["sequences"][1]["images"][:2]))
    with pytest.raises(ValueError, match=r"sequences\[1\]\.steps must be an integer in \[3, 1000\]; got 2"):
        read_capture(tmp_path)


def test_unknown_sequence_kind(tmp_path):
    _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][0].update(kind="gray"))
    message = r"sequences\[0\]\.kind must be 'phase' \(the default\) or 'graycode'; got 'gray'"
    with pytest.raises(ValueError, match=message):
        read_capture(tmp_path)


def test_graycode_image_count_and_coverage(tmp_path):
    rng = np.random.default_rng(0)
    write_capture(tmp_path, sequences=[PhaseFrames(images=_stack(3, rng), period=60),
                                       GraycodeFrames(images=_stack(4, rng), period=60)],
                  projector_size=(912, 1140))
    _edit_yaml(tmp_path, lambda d: d["sequences"][1]["images"].pop())
    with pytest.raises(ValueError, match=r"sequence 1 \(graycode, period 60\): 3 images listed but bits is 4"):
        read_capture(tmp_path)
    _edit_yaml(tmp_path, lambda d: d["sequences"][1].update(bits=3))
    with pytest.raises(ValueError, match=r"3 bits cover 2\*\*3 \* 60 = 480 projector pixels, less than the extent 912"):
        read_capture(tmp_path)


def test_graycode_inverse_and_complementary_need_the_complementary_inverse(tmp_path):
    rng = np.random.default_rng(0)
    write_capture(tmp_path, sequences=[
        PhaseFrames(images=_stack(3, rng), period=60),
        GraycodeFrames(images=_stack(4, rng), period=60, inverse=_stack(4, rng),
                       complementary=_stack(1, rng)[0], complementary_inverse=_stack(1, rng)[0])],
        projector_size=(912, 1140))
    _edit_yaml(tmp_path, lambda d: d["sequences"][1].pop("complementary_inverse"))
    with pytest.raises(ValueError, match=r"missing key 'sequences\[1\]\.complementary_inverse'"):
        read_capture(tmp_path)


def test_missing_image_files_are_all_named(tmp_path):
    capture, _ = _write_small(tmp_path)
    for path in capture.sequences[0].images[3:5]:
        path.unlink()
    with pytest.raises(FileNotFoundError, match=r"2 listed file\(s\) do not exist: seq0_f96_s03.png, seq0_f96_s04.png"):
        read_capture(tmp_path)


def test_folder_without_capture_yaml(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"capture\.yaml: no such file"):
        read_capture(tmp_path)


def test_yaml_that_is_not_a_mapping(tmp_path):
    (tmp_path / CAPTURE_FILE).write_text("- just\n- a list\n")
    with pytest.raises(ValueError, match=r"capture\.yaml: must be a mapping of keys"):
        read_capture(tmp_path)


# --------------------------------------------------------------------------------------------------
# Bad frames
# --------------------------------------------------------------------------------------------------

def test_image_of_the_wrong_size(tmp_path):
    capture, _ = _write_small(tmp_path)
    cv2.imwrite(str(capture.sequences[0].images[3]), np.zeros((12, 16), np.uint8))
    with pytest.raises(ValueError, match=r"seq0_f96_s03.png is 16x12, camera.size is 32x24"):
        load_sequence_images(capture, capture.sequences[0])


def test_sixteen_bit_image_declared_eight_bit(tmp_path):
    capture, _ = _write_small(tmp_path)
    cv2.imwrite(str(capture.sequences[0].images[0]), np.full(SHAPE, 300, np.uint16))
    with pytest.raises(ValueError, match=r"seq0_f96_s00.png is a 16-bit image, camera.bit_depth is 8"):
        load_sequence_images(capture, capture.sequences[0])


def test_eight_bit_image_declared_sixteen_bit(tmp_path):
    capture, _ = _write_small(tmp_path, dtype=np.uint16)
    cv2.imwrite(str(capture.sequences[1].images[2]), np.zeros(SHAPE, np.uint8))
    with pytest.raises(ValueError, match=r"seq1_p60_s02.png is an 8-bit image, camera.bit_depth is 16"):
        load_sequence_images(capture, capture.sequences[1])


def test_colour_image_is_rejected(tmp_path):
    capture, _ = _write_small(tmp_path)
    cv2.imwrite(str(capture.sequences[0].images[1]), np.zeros(SHAPE + (3,), np.uint8))
    with pytest.raises(ValueError, match=r"seq0_f96_s01.png is a colour image \(3 channels\); captures are mono"):
        load_sequence_images(capture, capture.sequences[0])


def test_file_that_is_not_an_image(tmp_path):
    capture, _ = _write_small(tmp_path)
    capture.sequences[0].images[2].write_bytes(b"not a png")
    with pytest.raises(ValueError, match=r"seq0_f96_s02.png: not an image OpenCV can read"):
        load_sequence_images(capture, capture.sequences[0])


def test_ground_truth_of_the_wrong_shape(tmp_path):
    capture, _ = _write_small(tmp_path)
    np.savez(tmp_path / "gt.npz", projector_x=np.zeros((3, 3), np.float32), valid=np.ones((3, 3), bool))
    _edit_yaml(tmp_path, lambda d: d.update(ground_truth="gt.npz"))
    message = r"gt.npz: projector_x must have the camera's shape \(H, W\) = \(24, 32\); got \(3, 3\)"
    with pytest.raises(ValueError, match=message):
        load_ground_truth(read_capture(tmp_path))


def test_ground_truth_that_is_not_an_npz_names_the_file(tmp_path):
    """np.load took other bytes for a pickle and failed with a message about pickles, naming no file (issue 19)."""
    capture, _ = _write_small(tmp_path)
    _edit_yaml(tmp_path, lambda d: d.update(ground_truth="gt.npz"))
    for content in (b"garbage\n", b"PK\x03\x04 cut short"):
        (tmp_path / "gt.npz").write_bytes(content)
        with pytest.raises(ValueError, match=r"gt\.npz: not a (readable )?ground-truth \.npz"):
            load_ground_truth(read_capture(tmp_path))


def test_write_capture_rejects_mixed_frame_formats(tmp_path):
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"all frames of a capture must share one dtype and size"):
        write_capture(tmp_path, sequences=[PhaseFrames(images=_stack(3, rng), frequency=8),
                                           PhaseFrames(images=_stack(3, rng, np.uint16), frequency=1)],
                      projector_size=(912, 1140))
    with pytest.raises(ValueError, match=r"images frames must be uint8 or uint16"):
        write_capture(tmp_path, sequences=[PhaseFrames(images=np.zeros((3,) + SHAPE), frequency=8)],
                      projector_size=(912, 1140))
