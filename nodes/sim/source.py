"""Where the sim node's frames come from: capture folders replayed, or scenes rendered live by the raycast twin.

A source is a list of :class:`SimScene`: for each scene, the camera frames of every pattern sequence it holds
(keyed by frequency and steps) and its ground truth. The sim node serves the frame a Trigger asks for from
the scene of that scan; nothing here knows about sockets or messages.

Sources (the sim node's ``source`` parameter):

- ``shipped``: the ``dptpu-capture/1`` folders under ``sim/shipped/`` (Blender renders of the twin, with
  ``gt.npz``), see :func:`shipped_root`, when they were made with the asked rig (its geometry and projector
  size) and hold the asked camera size and every asked sequence; otherwise (or when there are none) the scenes
  rendered live (``raycast``) with the asked rig instead, and :func:`load_source` says why in its note;
- ``raycast``: the scenes named by ``scenes`` rendered with :mod:`dptpu.sim.raycast` and
  :mod:`dptpu.sim.image_formation` at start-up (docs/benchmarks.md: how long per scene);
- a folder: one capture folder (it holds ``capture.yaml``) or a folder of capture folders (each a scene).

Convention: the ground truth is the projector coordinate along the fringe axis (0-based projector pixels) of
the surface point each camera pixel sees, valid where the projector lights it, and the depth along the camera
z axis in metres, NaN where no surface is seen.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import Rig, load_rig
from dptpu.fpp.capture import (
    CAPTURE_FILE,
    Capture,
    PhaseSequence,
    load_ground_truth,
    load_reference,
    load_sequence_images,
    read_capture,
)
from dptpu.fpp.frequencies import same_frequency
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.render import raycast_frames
from dptpu.sim.rig import load_twin_rig, parse_size
from dptpu.sim.scenes import load_scene, random_scene

__all__ = [
    "DEFAULT_SCENES",
    "SimScene",
    "SimSource",
    "capture_scenes",
    "load_source",
    "parse_scene_list",
    "parse_sequence_list",
    "raycast_scenes",
    "shipped_root",
]

#: Scenes rendered when the source is ``raycast`` (or ``shipped`` without shipped renders): seeded random
#: scenes of several objects with occlusions and depth steps, the standard sphere and the calibration board.
DEFAULT_SCENES = "random:1,sphere,random:2,board"
#: Reference frames a sequence may name besides its fringe sets: the projector full on, full off.
REFERENCES = ("white", "black")


@dataclass(frozen=True, eq=False)
class SimScene:
    """The frames and ground truth of one scene.

    Attributes
    ----------
    name : str
        E.g. ``sphere``, ``random-1`` or the capture folder's name.
    frames : dict
        ``(frequency, steps) -> ndarray (N, H, W)`` uint8 or uint16, step order (read-only).
    projector_coord : ndarray (H, W) float32
        Projector coordinate along the fringe axis, projector pixels; NaN where invalid.
    valid : ndarray (H, W) bool
        The projector lights the pixel's surface point.
    depth_m : ndarray (H, W) float32
        Depth along the camera z axis, metres; NaN where no surface.
    references : dict
        ``"white"`` / ``"black"`` -> (H, W) frame under the projector full on / full off (read-only), the ones the
        source has.
    has_truth : bool
        False for a capture without ground truth (no ``gt.npz``: a scan saved from a real rig by the cloud node's
        ``~/capture_and_save``): then ``projector_coord`` and ``depth_m`` are NaN and ``valid`` is False everywhere.
    """

    name: str
    frames: dict
    projector_coord: np.ndarray
    valid: np.ndarray
    depth_m: np.ndarray
    references: dict = field(default_factory=dict)
    has_truth: bool = True

    def stack(self, frequency: float, steps: int) -> np.ndarray | None:
        """The (N, H, W) frames of the sequence ``frequency x steps``, or None when the scene has none.

        A sequence of ``M`` steps, ``M`` a multiple of ``N``, holds the ``N``-step one: its frames ``0, M/N,
        2M/N, ...`` (image ``n`` is ``A + B cos(phi + sign 2 pi n / N)``, Eq. (1), and ``n/N = (n M/N) / M``), so
        12-step renders also serve 3-, 4- and 6-step sequences.
        """
        for (f, n), frames in self.frames.items():
            if n == steps and same_frequency(f, frequency):
                return frames
        for (f, n), frames in self.frames.items():
            if n % steps == 0 and same_frequency(f, frequency):
                return frames[:: n // steps]  # (steps, H, W) read-only view
        return None


@dataclass(frozen=True, eq=False)
class SimSource:
    """Scenes of one source, all of one camera size and one projector.

    Attributes
    ----------
    scenes : list of SimScene
    rig : Rig
        The rig the frames were made with (camera at the frames' size).
    fringe_axis : {"x", "y"}
    shift_sign : {-1, +1}
    kind : str
        ``raycast``, ``shipped`` or ``folder``.
    note : str
        What was chosen and why (e.g. the fallback from ``shipped`` to ``raycast``), for the node's log.
    """

    scenes: list
    rig: Rig
    fringe_axis: str = "x"
    shift_sign: int = -1
    kind: str = "raycast"
    note: str = ""
    sequences: tuple = field(default=())
    references: tuple = field(default=())  # the reference frames every scene has ("white", "black")

    @property
    def size(self) -> tuple[int, int]:
        """Camera ``(width, height)``."""
        width, height = self.rig.camera.size
        return (width, height)

    def describe_sequences(self) -> str:
        return ", ".join([f"{f:g}x{n}" for f, n in self.sequences] + list(self.references))

    def serves(self, frequency: float, steps: int) -> bool:
        """Whether the source's sequences hold ``frequency x steps``: one of that many steps, or of a multiple of
        it (:meth:`SimScene.stack`: 12-step renders serve 3-, 4- and 6-step sequences)."""
        return any(n % steps == 0 and same_frequency(f, frequency) for f, n in self.sequences)


def shipped_root() -> Path:
    """``sim/shipped``: the packaged twin renders (one ``dptpu-capture/1`` folder per scene)."""
    return Path(str(resources.files("dptpu.sim") / "shipped"))


def parse_scene_list(text: str) -> list[str]:
    """``"random:1,sphere,board"`` -> names; each a built-in (``sphere``, ``plane``, ``board``), ``random:SEED``
    or a scene file."""
    names = [token.strip() for token in str(text).split(",") if token.strip()]
    if not names:
        raise ValueError(f"parameter scenes must list at least one scene (e.g. {DEFAULT_SCENES}); got {text!r}")
    for name in names:
        if name.startswith("random:") and not name[7:].isdigit():
            raise ValueError(f"parameter scenes: {name!r} must be random:SEED with an integer seed (e.g. random:3)")
    return names


def parse_references(text: str) -> tuple[str, ...]:
    """The reference frames named in a sequence (``"64x12,1x12,white,black"`` -> ``("white", "black")``)."""
    return tuple(token.strip().lower() for token in str(text).split(",") if token.strip().lower() in REFERENCES)


def parse_sequence_list(text: str) -> list[tuple[float, int]]:
    """``"96x12,1x12"`` -> ``[(96.0, 12), (1.0, 12)]`` (frequency x steps, the projector node's syntax); the
    reference frames (``white``, ``black``) are left to :func:`parse_references`."""
    out = []
    for token in str(text).split(","):
        token = token.strip()
        if token.lower() in REFERENCES:
            continue
        frequency, sep, steps = token.partition("x")
        try:
            value = (float(frequency), int(steps))
        except ValueError:
            value = None
        if not sep or value is None or not value[0] > 0 or value[1] < 3:
            raise ValueError(f"parameter sequence: {token!r} must be FREQUENCYxSTEPS with frequency > 0 and "
                             f"steps >= 3 (e.g. 96x12,1x12)")
        out.append(value)
    return out


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array)
    array.flags.writeable = False
    return array


def raycast_scenes(rig: Rig, scene_names, sequences, *, fringe_axis: str = "x", shift_sign: int = -1,
                   seed: int = 0, bit_depth: int = 8, log=None, references=()) -> list[SimScene]:
    """Render each scene's frames of every sequence with the raycast twin: every stage of ``rig.effects``, the
    geometry stage included, as ``dptpu sim render`` (:func:`dptpu.sim.render.raycast_frames`).

    Parameters
    ----------
    rig : Rig
        Camera at the render size.
    scene_names : list of str
        Built-in names, ``random:SEED`` or scene files (:func:`dptpu.sim.scenes.load_scene`).
    sequences : list of (float, int)
        ``(frequency, steps)`` in projection order.
    seed : int
        Noise seed of the first scene (scene ``i`` uses ``seed + i``).
    log : callable, optional
        Called with one progress line per scene.
    references : sequence of str
        Reference frames rendered too (``"white"``, ``"black"``: the projector full on, full off).
    """
    specs = [SequenceSpec(f, n, axis=fringe_axis, shift_sign=shift_sign) for f, n in sequences]
    specs += [SequenceSpec(kind=kind) for kind in references]
    axis = 0 if fringe_axis == "x" else 1
    scenes = []
    for index, name in enumerate(scene_names):
        scene = random_scene(rig, int(name[7:])) if name.startswith("random:") else load_scene(name, rig)
        stacks, samples = raycast_frames(rig, scene, specs, seed=seed + index, bit_depth=bit_depth)
        frames = {(float(f), int(n)): _readonly(stack) for (f, n), stack in zip(sequences, stacks)}
        rendered_references = {kind: _readonly(stack[0]) for kind, stack in zip(references, stacks[len(sequences):])}
        coord = np.where(samples.lit, samples.projector_xy[..., axis], np.nan).astype(np.float32)
        depth_m = np.where(samples.hit, samples.depth * rig.scale_to_m, np.nan).astype(np.float32)
        scenes.append(SimScene(name=scene.name, frames=frames, projector_coord=_readonly(coord),
                               valid=_readonly(samples.lit.copy()), depth_m=_readonly(depth_m),
                               references=rendered_references))
        if log is not None:
            log(f"rendered scene {scene.name} ({index + 1} of {len(scene_names)}): {rig.camera.size[0]}x"
                f"{rig.camera.size[1]}, {sum(n for _, n in sequences) + len(references)} frames, "
                f"{100.0 * samples.lit.mean():.0f} % of pixels lit")
    return scenes


def _capture_folders(folder: Path) -> list[Path]:
    if (folder / CAPTURE_FILE).is_file():
        return [folder]
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if (p / CAPTURE_FILE).is_file())


def capture_scenes(folder) -> tuple[list[SimScene], Rig, str, int]:
    """Read the capture folder(s) under ``folder``: scenes, the rig, the fringe axis and the shift sign.

    Every capture must hold a ``calibration`` and share the camera size, fringe axis, shift sign and projector of
    the first one; its ``ground_truth`` (``gt.npz``, depth in the rig's units) is read when it has one (a capture of
    a real rig has none: its scene's ``has_truth`` is False).

    Raises
    ------
    ValueError
        No capture folder, or a capture without calibration, or captures that disagree (the message names the
        folder and what differs).
    """
    folders = _capture_folders(Path(folder))
    if not folders:
        raise ValueError(f"{folder}: no dptpu-capture/1 folder (a folder with {CAPTURE_FILE}, or a folder of them)")
    scenes: list[SimScene] = []
    rig: Rig | None = None
    first: Capture | None = None
    for path in folders:
        capture = read_capture(path)
        if capture.calibration is None:
            raise ValueError(f"{path}: the sim replays captures with a calibration (the rig the cloud node "
                             f"triangulates with); this one lacks calibration")
        if first is None:
            first, rig = capture, load_rig(capture.calibration)
        elif (capture.camera_size, capture.fringe_axis, capture.phase_shift_sign, capture.projector_size) != \
                (first.camera_size, first.fringe_axis, first.phase_shift_sign, first.projector_size):
            raise ValueError(f"{path}: camera size, fringe axis, shift sign and projector must be those of "
                             f"{first.root} ({first.camera_size}, {first.fringe_axis}, {first.phase_shift_sign}, "
                             f"{first.projector_size}); got ({capture.camera_size}, {capture.fringe_axis}, "
                             f"{capture.phase_shift_sign}, {capture.projector_size})")
        extent = capture.projector_size[0 if capture.fringe_axis == "x" else 1]
        frames = {}
        for sequence in capture.sequences:
            if isinstance(sequence, PhaseSequence):
                frames[(sequence.frequency_for(extent), int(sequence.steps))] = \
                    _readonly(load_sequence_images(capture, sequence))
        references = {}
        for kind in REFERENCES:
            image = load_reference(capture, kind)
            if image is not None:
                references[kind] = _readonly(image)
        if capture.ground_truth is None:  # a real rig's scan: frames only
            width, height = capture.camera_size
            scenes.append(SimScene(name=path.name, frames=frames,
                                   projector_coord=_readonly(np.full((height, width), np.nan, np.float32)),
                                   valid=_readonly(np.zeros((height, width), bool)),
                                   depth_m=_readonly(np.full((height, width), np.nan, np.float32)),
                                   references=references, has_truth=False))
            continue
        truth = load_ground_truth(capture)
        with np.load(capture.ground_truth) as data:
            coord = data["projector_y"] if capture.fringe_axis == "y" and "projector_y" in data.files \
                else truth.projector_x
            depth = data["depth"] if "depth" in data.files else np.full(truth.valid.shape, np.nan)
        depth_m = (np.asarray(depth, np.float64) * load_rig(capture.calibration).scale_to_m).astype(np.float32)
        scenes.append(SimScene(name=path.name, frames=frames,
                               projector_coord=_readonly(np.where(truth.valid, coord, np.nan).astype(np.float32)),
                               valid=_readonly(truth.valid), depth_m=_readonly(depth_m), references=references))
    if first is None or rig is None:  # folders is not empty: the first capture set both
        raise ValueError(f"{folder}: no capture read")
    return scenes, rig, first.fringe_axis, first.phase_shift_sign


def _shipped_lacks(scenes, rig: Rig, size, sequence, asked_rig=None) -> str:
    """What the shipped renders (made with ``rig``) lack of the asked rig, camera size and sequences ("" when they
    hold all)."""
    lacking = []
    width, height = parse_size(size)
    if asked_rig is not None:
        try:
            asked = load_twin_rig(asked_rig, size=tuple(rig.camera.size))  # at the renders' size: K comparable
        except (ValueError, FileNotFoundError):
            asked = None  # the live renders load it again and say what is wrong with it
        if asked is not None and not _same_geometry(asked, rig):
            ours, theirs = asked.projector.size, rig.projector.size
            lacking.append(f"the rig {asked_rig} (they were made with another rig; projector {theirs[0]}x{theirs[1]}"
                           f", the asked rig's {ours[0]}x{ours[1]})")
    if tuple(rig.camera.size) != (width, height):
        lacking.append(f"the size {width}x{height} (they are {rig.camera.size[0]}x{rig.camera.size[1]})")
    missing = [f"{f:g}x{n}" for f, n in parse_sequence_list(sequence) if scenes[0].stack(f, n) is None]
    missing += [kind for kind in parse_references(sequence) if kind not in scenes[0].references]
    if missing:
        held = ", ".join(f"{f:g}x{n}" for f, n in scenes[0].frames)
        lacking.append(f"the sequence(s) {', '.join(missing)} (they hold {held})")
    return " and ".join(lacking)


def _same_geometry(a: Rig, b: Rig) -> bool:
    """Whether two rigs (cameras of one size) have the same projector size, intrinsics and poses (1e-6)."""
    pairs = ((a.projector.K, b.projector.K), (a.projector.R, b.projector.R), (a.projector.T, b.projector.T),
             (a.camera.K, b.camera.K), (a.camera.R, b.camera.R), (a.camera.T, b.camera.T))
    return tuple(a.projector.size) == tuple(b.projector.size) and all(
        np.allclose(x, y, rtol=1e-6, atol=1e-6) for x, y in pairs)


def load_source(source: str, *, rig, size, scenes: str = DEFAULT_SCENES, sequence: str = "96x12,1x12",
                fringe_axis: str = "x", shift_sign: int = -1, seed: int = 0, bit_depth: int = 8,
                log=None, on_rig=None) -> SimSource:
    """The scenes of ``source`` (``shipped``, ``raycast`` or a folder; see the module docstring).

    Parameters
    ----------
    rig : str or Rig
        Raycast: the twin's rig (a rig file or ``nominal``, :func:`dptpu.sim.rig.load_twin_rig`).
    size : str or (int, int)
        Raycast: camera size ``WIDTHxHEIGHT``.
    scenes, sequence : str
        Raycast: :func:`parse_scene_list`, :func:`parse_sequence_list`.
    on_rig : callable, optional
        Raycast: ``on_rig(rig)`` is called with the twin's rig before the scenes are rendered, so a node can
        announce the camera while it renders.
    """
    note = ""
    if source not in ("shipped", "raycast"):
        found, twin_rig, axis, sign = capture_scenes(source)
        return SimSource(found, twin_rig, axis, sign, "folder", f"replaying {len(found)} capture(s) from {source}",
                         tuple(found[0].frames), _common_references(found))
    if source == "shipped":
        if _capture_folders(shipped_root()):
            found, twin_rig, axis, sign = capture_scenes(shipped_root())
            lacking = _shipped_lacks(found, twin_rig, size, sequence, rig)
            if not lacking:
                return SimSource(found, twin_rig, axis, sign, "shipped",
                                 f"replaying the {len(found)} shipped render(s) of {shipped_root()}",
                                 tuple(found[0].frames), _common_references(found))
            note = f"the shipped renders of {shipped_root()} lack {lacking}: rendering the scenes live with the " \
                   "raycast twin; "
        else:
            note = f"no shipped renders in {shipped_root()}: rendering the scenes live with the raycast twin; "
    if fringe_axis not in ("x", "y"):
        raise ValueError(f"parameter fringe_axis must be 'x' or 'y'; got {fringe_axis!r}")
    if shift_sign not in (-1, 1):
        raise ValueError(f"parameter shift_sign must be -1 or +1; got {shift_sign!r}")
    names = parse_scene_list(scenes)
    sequences = parse_sequence_list(sequence)
    try:
        twin_rig = load_twin_rig(rig, size=size)
    except FileNotFoundError as exc:
        raise ValueError(f"parameter rig: {exc}") from None
    if on_rig is not None:
        on_rig(twin_rig)
    references = parse_references(sequence)
    rendered = raycast_scenes(twin_rig, names, sequences, fringe_axis=fringe_axis, shift_sign=shift_sign, seed=seed,
                              bit_depth=bit_depth, log=log, references=references)
    return SimSource(rendered, twin_rig, fringe_axis, shift_sign, "raycast",
                     note + f"raycast renders of {', '.join(names)}", tuple((float(f), int(n)) for f, n in sequences),
                     references)


def _common_references(scenes) -> tuple[str, ...]:
    """The reference frames every scene has."""
    return tuple(kind for kind in REFERENCES if all(kind in scene.references for scene in scenes))
