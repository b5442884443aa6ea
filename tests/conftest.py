"""Shared test fixtures: where the real measured data lives, and synthetic fringe captures.

The real data sets (``cfpe/``, ``dptpu-sphere/``) are never copied into the repository. Tests read
them from ``$DPTPU_DATA`` when set, else from ``<repo>/../shared/data``, and skip with a clear reason
when they are absent.
"""
from __future__ import annotations

import signal
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from dptpu.fpp.measured_data import shared_data_dir

if TYPE_CHECKING:
    from dptpu.fpp.capture import GraycodeFrames, PhaseFrames

_MISSING_REASON = "real data not found: set DPTPU_DATA or place ../shared/data"


def pytest_configure(config):
    """Ctrl-C handled as Python's default, whoever started the suite: a shell runs a background job with SIGINT
    ignored, every process the tests start would inherit that, and the tests that stop a node with SIGINT (as
    Ctrl-C or the launcher does) would wait on a node that cannot hear it."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _data_set(name: str, probe: str) -> Path:
    folder = shared_data_dir() / name
    if not (folder / probe).exists():
        pytest.skip(f"{_MISSING_REASON} (looked for {folder / probe})")
    return folder


@pytest.fixture(scope="session")
def cfpe_dir() -> Path:
    """The CFPE raw fringe captures (``0100h.png`` ... ``0836h.png``), read-only."""
    return _data_set("cfpe", "0100h.png")


@pytest.fixture(scope="session")
def sphere_dir() -> Path:
    """The DP-TPU standard-sphere data (absolute phase maps and calibrations), read-only."""
    return _data_set("dptpu-sphere", "README.md")


# --------------------------------------------------------------------------------------------------
# Synthetic fringe captures (dptpu modules are imported lazily, so the data locator above works even
# while a module is broken)
# --------------------------------------------------------------------------------------------------

#: Projector of the synthetic captures, (width, height) pixels; fringe axis x, so the extent is 912.
SYNTHETIC_PROJECTOR_SIZE = (912, 1140)


@dataclass(frozen=True)
class SyntheticScene:
    """What a synthetic camera sees.

    projector_x : (H, W) int64 or float, the projector column seen by each camera pixel; integers
        sample the projector patterns exactly at pixel centres (floats are interpolated linearly).
    albedo : (H, W) float in (0, 1], scales the projected level.
    lit : (H, W) bool, False in a shadow where the albedo is ~0 (no usable modulation).
    """

    projector_x: np.ndarray
    albedo: np.ndarray
    lit: np.ndarray


def make_synthetic_scene(shape=(60, 80), seed=0) -> SyntheticScene:
    """A ramp of projector columns with a raised box (+67 px) and an isolated island (-230 px).

    The island is disconnected from the ramp around it, so only temporal unwrapping gets its orders
    right; the shadow in the top-left corner must come out invalid.
    """
    rng = np.random.default_rng(seed)
    height, width = shape
    rows, cols = np.mgrid[0:height, 0:width]
    projector_x = 30 + 10 * cols + rows // 6  # (H, W), 30 .. 830
    box = (rows >= 15) & (rows < 40) & (cols >= 20) & (cols < 50)
    island = (rows >= 45) & (rows < 56) & (cols >= 60) & (cols < 76)
    projector_x = projector_x + 67 * box - 230 * island
    albedo = 0.6 + 0.4 * rng.random(shape)
    lit = ~((rows < 9) & (cols < 16))
    albedo = np.where(lit, albedo, 0.01)
    assert projector_x.min() >= 0 and projector_x.max() < SYNTHETIC_PROJECTOR_SIZE[0]
    return SyntheticScene(projector_x=projector_x.astype(np.int64), albedo=albedo, lit=lit)


def _sample_rows(projector_rows: np.ndarray, projector_x: np.ndarray) -> np.ndarray:
    """Projector rows (N, extent) at projector coordinates (H, W): exact at integer ``projector_x``,
    linearly interpolated between pixel centres otherwise."""
    if np.issubdtype(projector_x.dtype, np.integer):
        return projector_rows[:, projector_x]
    columns = np.arange(projector_rows.shape[1], dtype=np.float64)
    return np.stack([np.interp(projector_x, columns, row) for row in projector_rows])


def _camera_frames(scene: SyntheticScene, projector_rows: np.ndarray, rng, noise_dn: float) -> np.ndarray:
    """Camera frames (N, H, W) uint8 of projector rows (N, extent) in digital numbers [0, 255]."""
    projected = _sample_rows(projector_rows, scene.projector_x)  # (N, H, W)
    levels = 8.0 + 0.9 * scene.albedo * projected + rng.normal(0.0, noise_dn, projected.shape)
    return np.clip(np.rint(levels), 0, 255).astype(np.uint8)


def render_phase_frames(scene, *, frequency=None, period=None, steps=12, shift_sign=-1, phase_offset=0.0,
                        noise_dn=0.5, rng=None) -> PhaseFrames:
    """A phase sequence as the camera sees it: ``fringe_patterns`` sampled at ``scene.projector_x``."""
    from dptpu.fpp.capture import PhaseFrames
    from dptpu.fpp.patterns import fringe_patterns

    rng = rng if rng is not None else np.random.default_rng(0)
    patterns = fringe_patterns(frequency=frequency, period=period, steps=steps,
                               projector_size=(SYNTHETIC_PROJECTOR_SIZE[0], 1), shift_sign=shift_sign,
                               phase_offset=phase_offset, dtype=float)  # (N, 1, 912)
    return PhaseFrames(images=_camera_frames(scene, patterns[:, 0, :], rng, noise_dn), frequency=frequency,
                       period=period, phase_offset=phase_offset)


def render_graycode_frames(scene, *, bits, period, inverse=True, complementary=True, noise_dn=0.5,
                           rng=None) -> GraycodeFrames:
    """A (complementary) Gray-code sequence as the camera sees it."""
    from dptpu.fpp.capture import GraycodeFrames
    from dptpu.fpp.graycode import graycode_patterns

    rng = rng if rng is not None else np.random.default_rng(1)
    code = graycode_patterns(bits, period, (SYNTHETIC_PROJECTOR_SIZE[0], 1), inverse=inverse,
                             complementary=complementary)

    def frames(stack):
        return None if stack is None else _camera_frames(scene, np.asarray(stack, float)[:, 0, :], rng, noise_dn)

    def frame(image):
        return None if image is None else frames(np.asarray(image)[None])[0]

    return GraycodeFrames(images=frames(code.images), period=period, inverse=frames(code.inverse),
                          complementary=frame(code.complementary),
                          complementary_inverse=frame(code.complementary_inverse))


@pytest.fixture
def synthetic_capture(tmp_path):
    """Factory: write a synthetic capture folder of :func:`make_synthetic_scene`; returns ``(folder, scene)``.

    ``make(specs, *, name="capture", phase_shift_sign=-1, scene=None, noise_dn=0.5, with_references=False,
    **write_capture_options)``
    with ``specs`` a list of dicts: ``{"frequency": 64}`` or ``{"period": 42, "steps": 12, "phase_offset": 0.3}``
    for phase sequences (rendered with ``shift_sign=phase_shift_sign``), ``{"kind": "graycode", "bits": 6,
    "period": 16, "inverse": True, "complementary": True}`` for Gray code. ``with_references`` adds white
    and black reference frames (the projector full on and full off). ``scene`` may be any object with
    the attributes of :class:`SyntheticScene` (e.g. a ``SimpleNamespace``). The folder gets
    ``ground_truth.npz`` with the scene's ``projector_x`` and ``lit`` mask.
    """
    from dptpu.fpp.capture import write_capture

    def make(specs, *, name="capture", phase_shift_sign=-1, scene=None, noise_dn=0.5, with_references=False,
             **options):
        scene = scene if scene is not None else make_synthetic_scene()
        rng = np.random.default_rng(0)
        if with_references:  # the camera's view of the projector full on and full off
            full_on_off = np.array([[255.0] * SYNTHETIC_PROJECTOR_SIZE[0], [0.0] * SYNTHETIC_PROJECTOR_SIZE[0]])
            white, black = _camera_frames(scene, full_on_off, rng, noise_dn)
            options["references"] = {"white": white, "black": black}
        frames = []
        for spec in specs:
            spec = dict(spec)
            if spec.pop("kind", "phase") == "graycode":
                frames.append(render_graycode_frames(scene, noise_dn=noise_dn, rng=rng, **spec))
            else:
                frames.append(render_phase_frames(scene, shift_sign=phase_shift_sign, noise_dn=noise_dn, rng=rng,
                                                  **spec))
        folder = tmp_path / name
        write_capture(folder, sequences=frames, projector_size=SYNTHETIC_PROJECTOR_SIZE, fringe_axis="x",
                      phase_shift_sign=phase_shift_sign,
                      ground_truth={"projector_x": scene.projector_x.astype(np.float32), "valid": scene.lit},
                      **options)
        return folder, scene

    return make
