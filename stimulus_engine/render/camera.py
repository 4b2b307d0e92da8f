"""Cameras: a plain look-at perspective camera and the two framings the renderer offers.

* :func:`fit_camera` frames a bounding box from the front (for previews of any mesh).
* :func:`face_camera` frames a face so that the midpoint between the eyes lands at a fixed image
  position and the face length covers a fixed fraction of the image height. Using it with each
  stimulus's own landmarks gives every image of a set the same face size and eye position
  (thesis §7.3: ERP stimuli must not differ in low-level layout).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CameraSpec", "face_camera", "fit_camera"]


@dataclass(frozen=True)
class CameraSpec:
    """A perspective camera looking from ``position`` at ``target``.

    Attributes
    ----------
    position, target : tuple of float
        World coordinates.
    yfov_deg : float
        Vertical field of view in degrees.
    up : tuple of float
        World up direction.
    """

    position: tuple[float, float, float]
    target: tuple[float, float, float]
    yfov_deg: float = 20.0
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    @property
    def distance(self) -> float:
        """Distance from the camera to its target."""
        return float(np.linalg.norm(np.subtract(self.position, self.target)))

    def rotation(self) -> np.ndarray:
        """3 × 3 camera-to-world rotation (columns: image right, image up, towards the viewer)."""
        z = np.subtract(self.position, self.target).astype(float)
        z /= np.linalg.norm(z)
        x = np.cross(np.asarray(self.up, float), z)
        if np.linalg.norm(x) < 1e-9:
            raise ValueError("camera up direction is parallel to the viewing direction")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return np.stack([x, y, z], axis=1)

    def pose(self) -> np.ndarray:
        """4 × 4 camera-to-world matrix (OpenGL convention: the camera looks along its -z)."""
        m = np.eye(4)
        m[:3, :3] = self.rotation()
        m[:3, 3] = self.position
        return m

    def describe(self) -> str:
        """A compact one-line description (written to grid manifests)."""
        p = ",".join(f"{v:.4g}" for v in self.position)
        t = ",".join(f"{v:.4g}" for v in self.target)
        return f"pos=({p}) target=({t}) yfov={self.yfov_deg:.4g}"


def fit_camera(points: np.ndarray, aspect: float, *, yfov_deg: float = 20.0, margin: float = 1.15,
               view_dir: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> CameraSpec:
    """A camera that sees the whole bounding box of ``points`` from ``view_dir``.

    Parameters
    ----------
    points : (n, 3) array
        Vertices to frame.
    aspect : float
        Image width / height.
    yfov_deg : float
        Vertical field of view.
    margin : float
        Extra room around the box (1 = tight).
    view_dir : tuple of float
        Direction from the target towards the camera (default: from the front, +z).
    """
    pts = np.asarray(points, float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2 * margin
    half = math.radians(yfov_deg) / 2
    dist = radius / math.sin(min(half, math.atan(math.tan(half) * aspect)))
    d = np.asarray(view_dir, float)
    d /= np.linalg.norm(d)
    pos = centre + d * dist
    return CameraSpec(tuple(float(v) for v in pos), tuple(float(v) for v in centre), yfov_deg)


def face_camera(eye_mid: np.ndarray, face_length: float, *, yfov_deg: float = 20.0, eye_row: float = 0.42,
                face_fraction: float = 0.55, view_dir: tuple[float, float, float] = (0.0, 0.0, 1.0),
                up: tuple[float, float, float] = (0.0, 1.0, 0.0)) -> CameraSpec:
    """Frame a face: eye midpoint at row ``eye_row`` of the image, face length = ``face_fraction`` of its height.

    Parameters
    ----------
    eye_mid : (3,) array
        Midpoint between the two eye centres (world).
    face_length : float
        A length on the face (e.g. brow-to-chin) in world units; it will span
        ``face_fraction`` of the image height at the depth of ``eye_mid``.
    yfov_deg : float
        Vertical field of view (a long lens, as for portraits, keeps perspective mild).
    eye_row : float
        Vertical eye position as a fraction of the image height from the top.
    face_fraction : float
        Fraction of the image height the face length covers.
    view_dir, up : tuple of float
        Direction from the face towards the camera, and world up.

    Returns
    -------
    CameraSpec
        The camera looks parallel to ``-view_dir``; its target is shifted so the eyes project to
        (image centre column, ``eye_row``).
    """
    if face_length <= 0:
        raise ValueError(f"face_length must be > 0 (got {face_length})")
    tan_half = math.tan(math.radians(yfov_deg) / 2)
    dist = face_length / (face_fraction * 2 * tan_half)
    d = np.asarray(view_dir, float)
    d /= np.linalg.norm(d)
    u = np.asarray(up, float) - d * np.dot(up, d)
    u /= np.linalg.norm(u)
    # eyes at normalised device y = (0.5 - eye_row) * 2 -> shift the target down by that much
    shift = (0.5 - eye_row) * 2 * dist * tan_half
    target = np.asarray(eye_mid, float) - u * shift
    pos = target + d * dist
    return CameraSpec(tuple(float(v) for v in pos), tuple(float(v) for v in target), yfov_deg, tuple(float(v) for v in u))
