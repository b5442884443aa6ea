"""The phase node in the in-process harness: frames of the analytic plane in, PhaseMaps and ScanStatus out."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.phase_harmonics import ProjectorPhaseResponse, fit_harmonic_phase_error
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import FringeFrame, Image, PatternEntry, PatternSequence, PhaseMaps, ScanStatus
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from tests.nodes.test_cloud_scene import EXTENT_PX, plane_scene

FREQUENCIES = (16.0, 1.0)
# Phase noise of 4 steps at 0.5 DN noise + uint8 rounding and B ~ 80 DN: sqrt(2/4) * 0.6 / 80 = 0.005 rad;
# np.interp of the projector pattern adds < 0.002 rad. Measured: RMS 0.005 rad, max 0.021 rad over 19,200 pixels.
MAX_PHASE_ERROR_RAD = 0.04


@pytest.fixture(scope="module")
def scene():
    return plane_scene()


@pytest.fixture
def harness():
    with NodeHarness() as harness:
        yield harness


def start(harness, **parameters):
    node = harness.start(PhaseNode, **{"timeout_s": 0.4, **parameters})
    camera = harness.publisher(FringeFrame, "/camera/image_raw")
    phase = harness.collect(PhaseMaps, "/scanner/phase")
    status = harness.collect(ScanStatus, "/scanner/status")
    harness.connect()
    return node, camera, phase, status


def circular_error(a, b):
    return np.abs(np.angle(np.exp(1j * (a - b))))


def test_phase_maps_of_the_plane_match_the_analytic_wrapped_phase(harness, scene):
    node, camera, phase, status = start(harness)
    for frame in fringe_frames([scene.frames(f) for f in FREQUENCIES], FREQUENCIES, sequence_id=11):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)
    assert maps.sequence_id == 11 and maps.frequencies.tolist() == list(FREQUENCIES)
    assert maps.phases.shape == (2, 120, 160) and maps.phases.dtype == np.float32
    assert maps.valid.all()  # every pixel sees the fringes with B ~ 80 DN
    for index, frequency in enumerate(FREQUENCIES):
        assert circular_error(maps.phases[index], scene.wrapped_phase(frequency)).max() < MAX_PHASE_ERROR_RAD
    assert 0.0 <= maps.phases.min() and maps.phases.max() < 2 * np.pi
    assert 70 < float(np.median(maps.modulation)) < 90  # 0.9 * 0.8 * 0.45 * 255 = 82.6 DN
    (ok,) = harness.wait(status, 1)
    assert (ok.level, ok.state, ok.sequence_id, ok.frames_received) == (ScanStatus.OK, "processing", 11, 8)
    assert (ok.valid_pixels, ok.total_pixels, ok.node) == (19200, 19200, "/phase")


def test_incomplete_scan_reports_why_after_the_timeout_and_the_next_scan_is_fine(harness, scene):
    node, camera, phase, status = start(harness)
    stacks = [scene.frames(f) for f in FREQUENCIES]
    frames = fringe_frames(stacks, FREQUENCIES, sequence_id=1)
    for frame in frames[:5] + frames[6:]:  # pattern 5 (f=1, step 1) never arrives
        camera.publish(frame)
    (failed,) = harness.wait(status, 1)
    assert (failed.level, failed.state, failed.sequence_id) == (ScanStatus.ERROR, "failed", 1)
    assert failed.reason == "incomplete after 0.4 s: received 7 of 8 frames; missing pattern 5"
    assert (failed.frames_expected, failed.frames_received, failed.frames_dropped) == (8, 7, 7)
    assert failed.duration_s >= 0.4
    for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=2):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)
    assert maps.sequence_id == 2 and node.scans_dropped == 1 and node.scans_published == 1


def test_interleaved_scans_over_the_wire_are_never_mixed(harness, scene):
    node, camera, phase, status = start(harness)
    scans = {21: (16.0, 1.0), 22: (12.0, 1.0)}  # two scans of different frequencies
    frames = {i: fringe_frames([scene.frames(f, seed=i) for f in fs], fs, sequence_id=i) for i, fs in scans.items()}
    for a, b in zip(frames[21], frames[22]):
        camera.publish(a)
        camera.publish(b)
    maps = {m.sequence_id: m for m in harness.wait(phase, 2)}
    for sequence_id, frequencies in scans.items():
        assert maps[sequence_id].frequencies.tolist() == list(frequencies)
        error = circular_error(maps[sequence_id].phases[0], scene.wrapped_phase(frequencies[0]))
        assert error.max() < MAX_PHASE_ERROR_RAD


def test_malformed_frames_are_counted_and_reported_and_the_node_stays_up(harness, scene):
    node, camera, phase, status = start(harness)
    stacks = [scene.frames(f) for f in FREQUENCIES]
    frames = fringe_frames(stacks, FREQUENCIES, sequence_id=31)
    frames[3].image = Image.from_array(np.zeros((60, 80), np.uint8), header=frames[3].image.header)  # wrong size
    for frame in frames:
        camera.publish(frame)
    float_frames = fringe_frames(stacks, FREQUENCIES, sequence_id=32)
    float_frames[0].image = Image.from_array(np.full((120, 160), np.nan, np.float32))  # NaN, not a camera frame
    camera.publish(float_frames[0])
    for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=33):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)
    assert maps.sequence_id == 33
    failed = {s.sequence_id: s for s in harness.wait(status, 3) if s.state == "failed"}
    assert "pattern 3 (f=16, step 3 of 4) is 80x60 uint8; the scan's first frame was 160x120 uint8" \
        in failed[31].reason
    assert "image encoding must be mono8 or mono16; got '32FC1'" in failed[32].reason
    assert node.scans_dropped == 2 and node.frames_rejected == 4  # patterns 4..7 of scan 31 came after its failure


def test_pattern_sequence_sets_the_layout_and_an_unknown_frequency_fails_the_scan(harness, scene):
    node, camera, phase, status = start(harness)
    layout = harness.publisher(PatternSequence, "/projector/pattern_sequence",
                               QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    harness.connect()
    layout.publish(PatternSequence(entries=[PatternEntry(frequency=16.0, steps=4),
                                            PatternEntry(period=EXTENT_PX, steps=4, phase_offset=0.0)],
                                   fringe_axis="x", projector_width=912, projector_height=1140, shift_sign=-1))
    assert harness.spin_until(lambda: node.assembler.layout is not None)
    assert node.assembler.layout.frequencies == (16.0, 1.0)  # the period of 912 px is 1 period per extent
    stacks = [scene.frames(f) for f in FREQUENCIES]
    for frame in fringe_frames(stacks, (16.0, 2.0), sequence_id=41):
        camera.publish(frame)
    for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=42):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)
    assert (maps.sequence_id, maps.projector_width, maps.projector_height) == (42, 912, 1140)
    (failed,) = [s for s in harness.wait(status, 2) if s.state == "failed"]
    assert "unknown frequency 2 for pattern 4; the PatternSequence has 1 there (frequencies 16, 1)" in failed.reason


def test_bad_parameters_are_refused_with_the_parameter_name(harness):
    with pytest.raises(ValueError, match="min_modulation must be >= 0; got -1"):
        harness.start(PhaseNode, min_modulation=-1.0)
    with pytest.raises(ValueError, match="timeout_s must be a number of seconds > 0"):
        harness.start(PhaseNode, timeout_s=0.0)


def _through_gamma(frames: np.ndarray, gamma: float = 2.2) -> np.ndarray:
    """A nonlinear response (the projector's and the camera's act alike on the frames): level ** gamma."""
    return np.round(255.0 * (frames / 255.0) ** gamma).astype(np.uint8)


@pytest.mark.parametrize("with_rig, bound", [(False, (0.1, np.inf)), (True, (0.0, 0.02))])
def test_the_rigs_projector_response_corrects_the_3_step_phases(harness, scene, tmp_path, with_rig, bound):
    """The response fitted on 12-step against 3-step frames of one scan, given as the rig parameter, takes another
    scan's 3-step phase error from the gamma's to the noise (measured: 0.172 -> 0.0079 rad RMS; the fit's first term
    -0.241 rad, 0.5 DN of noise on 3 steps); without the rig the error stays."""
    psi = [wrapped_phase(_through_gamma(scene.frames(16.0, steps=steps, seed=9))).phase for steps in (3, 12)]
    error = fit_harmonic_phase_error([psi[0]], [psi[1]], [np.ones(psi[0].shape, bool)], steps=3, multiples=3)
    rig = dataclasses.replace(scene.rig, phase_response=ProjectorPhaseResponse({3: error}))
    parameters = {"rig": str(save_rig(rig, tmp_path / "rig.yaml"))} if with_rig else {}
    node, camera, phase, _ = start(harness, **parameters)
    for frame in fringe_frames([_through_gamma(scene.frames(f, steps=3, seed=4)) for f in FREQUENCIES], FREQUENCIES,
                               sequence_id=5):
        camera.publish(frame)
    (maps,) = harness.wait(phase, 1)
    assert maps.phases.dtype == np.float32 and 0 <= maps.phases.min() and maps.phases.max() < 2 * np.pi
    rms = float(np.sqrt(np.mean(circular_error(maps.phases[0], scene.wrapped_phase(16.0)) ** 2)))
    assert bound[0] < rms < bound[1]
