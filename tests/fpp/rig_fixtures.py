"""A plausible synthetic rig for tests: camera at the origin, projector 170 mm to the side, 6.21 deg toe-in."""
import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig


def rotation(axis: str, degrees: float) -> np.ndarray:
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def synthetic_rig(*, distortion: bool = True, camera_size=(640, 480), baseline: str = "x") -> Rig:
    """Rig with the projector displaced along ``baseline`` ("x": to the right, for vertical fringes; "y": below,
    for horizontal fringes), its axis turned towards the camera axis."""
    width, height = camera_size
    scale = width / 640
    camera = DeviceModel(K=[[2600 * scale, 0.3, width / 2 - 0.5 + 9], [0, 2601 * scale, height / 2 - 0.5 - 4],
                            [0, 0, 1]],
                         dist=[-0.13, -0.5, -0.0014, -0.0004, 0.0] if distortion else np.zeros(5),
                         R=np.eye(3), T=np.zeros(3), size=camera_size)
    if baseline == "x":
        R_p, offset = rotation("y", 6.21), np.array([170.0, 0.0, 0.0])
    else:
        R_p, offset = rotation("x", -6.21), np.array([0.0, 170.0, 0.0])
    projector = DeviceModel(K=[[1730, -0.9, 443], [0, 3460, 588], [0, 0, 1]],
                            dist=[-0.05, 1.5, 0.001, 0.001, 0.0] if distortion else np.zeros(5),
                            R=R_p, T=-R_p @ offset, size=(912, 1140))
    return Rig(camera=camera, projector=projector, units="mm")
