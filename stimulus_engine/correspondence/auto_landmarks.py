"""The 68 iBUG landmarks of a face mesh, found automatically (``landmarks: auto``, issue 14).

A mesh is rendered (pyrender, its own texture; a mesh without one is shaded light grey) and
dlib's 68-point detector (:func:`stimulus_engine.morphpca.keypoints.detect_landmarks_scored`,
offline weights) finds the face in the image; each 2D point is lifted onto the surface through
the depth buffer, and the views are combined:

1. **Which way is the front?** A scan's axes are whatever its scanner used, and dlib's detector
   finds only upright faces, so both the view direction and the image's up are searched over
   the mesh's axes: first the six views of the y-up and z-up conventions (:data:`AXIS_VIEWS`),
   then the other 18 (direction, up) pairs (:data:`OTHER_AXIS_VIEWS`: on its side, upside
   down); the view where dlib's face score is highest is the front. The axes, not the PCA axes,
   because a head's principal axes (bust, neck, hair) need not point out of the face, whereas
   a scan is almost always stored upright along some axis. Meshes with no face in any view are
   refused (one line) - rotate them upright or give the landmarks by hand.
2. **Nearby views.** From the front and four views around it (yaw ±``yaw_deg``, pitch
   ±``pitch_deg``) the 68 points are detected and lifted: pixel -> camera ray -> the depth
   buffer's distance -> a 3D point, snapped to the closest surface point. A point whose pixel
   shows no surface (a jaw point on the silhouette) is looked up in its 5 x 5 neighbourhood.
3. **Combination** (:func:`combine_views`). Per landmark, the median of its lifted points over
   the views that saw it; a view's point further than ``OUTLIER_PCT`` (2 %) of the mesh's
   bounding-box diagonal from that median is dropped as an outlier (a detection that slipped, a
   silhouette point lifted onto another part of the surface) and the rest are averaged, then
   snapped to the closest surface point. Its confidence is the share of views that saw it and
   agreed (inliers) times ``exp(-spread / (1 % of the diagonal))``, with spread the median
   distance of the views' points from the combined point — points seen by all views, which
   agree, score near 1.

The jaw line (points 0-16) is a silhouette in a 2D detector: where it lies on the 3D surface
depends on the view, so its confidence is lower and its error larger than the inner points'.
Measured by ``benchmarks/auto_landmarks.py`` (error in % of the bounding-box diagonal, mean /
largest; 2-core machine, OSMesa, 640 px renders; also in docs/correspondence.md):

=====================================  ==============  ============  ======
mesh                                   inner 17-67     jaw 0-16      time
=====================================  ==============  ============  ======
menpo3d james (textured scan)          0.73 / 2.0      4.5 / 10.0    4.6 s
ICT generic neutral (untextured, grey) 1.15 / 3.4     2.3 / 6.9     2.5 s
Lee Perry-Smith (textured, no truth)   —               —             3.0 s
=====================================  ==============  ============  ======

Times: the fastest of four runs; with the two cores shared by other work they rose to 6-8 s. The
ground truths: james's ``james.ljson`` (menpo, reordered to iBUG by
``landmark_sets.reorder_landmarks``) and the ICT mesh's ``vertex_indices.json`` 'landmarks'
(Multi-PIE 68, iBUG order: every inner point lands within 3.4 % and every jaw point within 6.9 %
of the detected point of its own index). Without the outlier step (plain median) the inner means
were 0.75 % (james) and 1.22 % (ICT); the 5 views vote too few times for the step to do more
than guard against a slipped detection. The ICT truth places the brows higher than dlib does on
an untextured head (no brow hair to see): its brows are off by 2.2 %, its eyes 1.35 %, nose
and mouth 0.6-0.75 %.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import trimesh

from appeal.errors import AppealInputError
from stimulus_engine.correspondence.points import SurfacePoints, closest_surface_points

__all__ = ["MeshLandmarks", "detect_mesh_landmarks", "merge_landmarks", "lift_views", "combine_views", "AXIS_VIEWS",
           "OTHER_AXIS_VIEWS", "ALL_AXIS_VIEWS", "OUTLIER_PCT"]

#: A view's lifted point this far (in % of the bounding-box diagonal) from the views' median is an outlier.
OUTLIER_PCT = 2.0

#: (view direction from the mesh's centre towards the camera, image up) tried first for the front:
#: the y-up and z-up conventions of most scanners and modelling tools.
AXIS_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "+z": ((0, 0, 1), (0, 1, 0)), "-z": ((0, 0, -1), (0, 1, 0)),
    "+x": ((1, 0, 0), (0, 1, 0)), "-x": ((-1, 0, 0), (0, 1, 0)),
    "+y": ((0, 1, 0), (0, 0, 1)), "-y": ((0, -1, 0), (0, 0, 1)),
}


def _other_views() -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]:
    axes = {f"{sign}{name}": tuple(float(sign + "1") if i == j else 0.0 for j in range(3))
            for i, name in enumerate("xyz") for sign in "+-"}
    return {f"{d}/up{u}": (axes[d], axes[u]) for d in axes for u in axes
            if d[1] != u[1] and (axes[d], axes[u]) not in AXIS_VIEWS.values()}

#: The other 18 (direction, up) pairs of the axes (key "+x/up+z": looking from +x, +z up), tried
#: when no face is found in :data:`AXIS_VIEWS` (a mesh lying on its side, upside down, or y-down
#: as in camera coordinates): dlib's detector finds upright faces only.
OTHER_AXIS_VIEWS = _other_views()
ALL_AXIS_VIEWS = {**AXIS_VIEWS, **OTHER_AXIS_VIEWS}

@dataclass
class MeshLandmarks:
    """Landmarks of a mesh in iBUG 68 order.

    Attributes
    ----------
    points : (68, 3) array
        On the surface.
    surface : SurfacePoints
        The same points as (triangle corners, barycentric weights).
    confidence : (68,) array in [0, 1]
    front : str
        The axis view (a key of :data:`ALL_AXIS_VIEWS`) taken as the front.
    views : int
        Views the face was found in.
    scores : dict of str to float
        dlib's face score per view it was found in, by view (``front``, ``yaw+15``, ``yaw-15``,
        ``pitch+10``, ``pitch-10``): the views used.
    """

    points: np.ndarray
    surface: SurfacePoints
    confidence: np.ndarray
    front: str
    views: int
    scores: dict[str, float]


def _rotate(v: np.ndarray, axis: np.ndarray, deg: float) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(math.radians(deg), axis)[:3, :3] @ v


def _drawable(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh as drawn for the detector: its texture, or light grey when it has none."""
    from stimulus_engine.geometry.mesh_io import texture_image

    if texture_image(mesh) is not None:
        return mesh
    grey = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    grey.visual = trimesh.visual.ColorVisuals(grey, vertex_colors=np.tile([190, 190, 190, 255], (len(mesh.vertices), 1)))
    return grey


class _View:
    """A camera around the mesh and its render (image, depth)."""

    def __init__(self, mesh: trimesh.Trimesh, centre: np.ndarray, radius: float, direction: np.ndarray,
                 up: np.ndarray, size: int, yfov_deg: float = 30.0) -> None:
        from stimulus_engine.render import CameraSpec, render_mesh

        self.size, self.yfov = size, math.radians(yfov_deg)
        dist = radius / math.tan(self.yfov / 2) * 1.05
        self.camera = CameraSpec(tuple(centre + direction * dist), tuple(centre), yfov_deg, tuple(up))
        self.image, self.depth = render_mesh(mesh, width=size, height=size, camera=self.camera, lighting="gi_soft",
                                             shadows=False, return_depth=True)

    def lift(self, xy: np.ndarray, window: int = 2) -> np.ndarray:
        """3D points under image points ``xy`` (n, 2); NaN where no surface is near the pixel."""
        out = np.full((len(xy), 3), np.nan)
        rot, pos = self.camera.rotation(), np.asarray(self.camera.position, float)
        t = math.tan(self.yfov / 2)
        for i, (x, y) in enumerate(xy):
            xi, yi = int(round(x)), int(round(y))
            if not (0 <= xi < self.size and 0 <= yi < self.size):
                continue
            d = self.depth[yi, xi]
            if d <= 0:  # on the silhouette: the nearest surface pixel around it
                y0, x0 = max(yi - window, 0), max(xi - window, 0)
                patch = self.depth[y0: yi + window + 1, x0: xi + window + 1]
                hit = np.argwhere(patch > 0)
                if len(hit) == 0:
                    continue
                j = hit[np.argmin(((hit - [yi - y0, xi - x0]) ** 2).sum(axis=1))]
                yi, xi, d = y0 + j[0], x0 + j[1], patch[j[0], j[1]]
            xn = (xi + 0.5) / self.size * 2 - 1
            yn = 1 - (yi + 0.5) / self.size * 2
            out[i] = rot @ np.array([xn * t * d, yn * t * d, -d]) + pos
        return out


def lift_views(drawn: trimesh.Trimesh, centre: np.ndarray, radius: float, direction: np.ndarray, up: np.ndarray, *,
               name: str = "mesh", size: int = 640, yaw_deg: float = 15.0,
               pitch_deg: float = 10.0) -> tuple[np.ndarray, dict[str, float]]:
    """The 68 points detected in the front view and four around it, lifted to 3D.

    Returns
    -------
    stack : (views, 68, 3) array
        One row per view in which dlib found a face (NaN where a point's pixel shows no surface).
    scores : dict of str to float
        dlib's face score per returned view, by view name (``front``, ``yaw+15``, ``pitch-10``...).
    """
    from stimulus_engine.morphpca.keypoints import detect_landmarks_scored

    right = np.cross(up, direction)
    turns = {"front": (up, 0.0), f"yaw+{yaw_deg:g}": (up, yaw_deg), f"yaw-{yaw_deg:g}": (up, -yaw_deg),
             f"pitch+{pitch_deg:g}": (right, pitch_deg), f"pitch-{pitch_deg:g}": (right, -pitch_deg)}
    lifted, scores = [], {}
    for view_name, (axis, deg) in turns.items():
        view = _View(drawn, centre, radius, _rotate(direction, axis, deg), _rotate(up, axis, deg), size)
        try:
            xy, score = detect_landmarks_scored(view.image, name, max_side=size)
        except AppealInputError:
            continue
        lifted.append(view.lift(xy))
        scores[view_name] = score
    return (np.stack(lifted) if lifted else np.zeros((0, 68, 3))), scores


def combine_views(stack: np.ndarray, diag: float, *, outlier_pct: float = OUTLIER_PCT,
                  scale_pct: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """One point per landmark from its lifted points in several views, and a confidence.

    Parameters
    ----------
    stack : (views, n, 3) array
        Lifted points; NaN where a view did not see the point.
    diag : float
        The mesh's bounding-box diagonal (the unit of the tolerances).
    outlier_pct : float
        A view's point further than this (in % of ``diag``) from the median of the views is
        dropped as an outlier (a detection that slipped, or a silhouette point lifted onto a
        different part of the surface); the rest are averaged.
    scale_pct : float
        The spread (in % of ``diag``) at which agreement falls to ``1/e``.

    Returns
    -------
    points : (n, 3) array
        Mean of the inlier points (the median where no view is within ``outlier_pct``).
    confidence : (n,) array in [0, 1]
        Share of views that saw the point and agreed with the others (inliers) times
        ``exp(-spread / scale)``, with spread the median distance of the seen points from
        ``points``: points seen by all views which agree score near 1.
    """
    stack = np.asarray(stack, dtype=np.float64)
    seen = ~np.isnan(stack[..., 0])
    median = np.nanmedian(stack, axis=0)
    dist = np.linalg.norm(stack - median[None], axis=2)
    inlier = seen & (dist <= outlier_pct / 100 * diag)
    n_in = inlier.sum(axis=0)
    mean = np.where(inlier[..., None], stack, 0.0).sum(axis=0) / np.maximum(n_in, 1)[:, None]
    points = np.where((n_in > 0)[:, None], mean, median)
    spread = np.nanmedian(np.where(seen, np.linalg.norm(stack - points[None], axis=2), np.nan), axis=0)
    confidence = inlier.mean(axis=0) * np.exp(-spread / (scale_pct / 100 * diag))
    return points, confidence


#: dlib's face score above which an axis view is taken as the front without trying the others
#: (frontal renders of the james, Lee Perry-Smith, ICT and MediaPipe meshes score 1.2–1.5;
#: side views find no face or score about 0.1).
CONFIDENT_FRONT = 0.8


def _find_front(mesh: trimesh.Trimesh, centre: np.ndarray, radius: float, size: int,
                name: str) -> tuple[str, np.ndarray, np.ndarray, np.ndarray, float]:
    """The axis view with dlib's best face score: (key, direction, up, centre, radius) of it.

    The six :data:`AXIS_VIEWS` are tried framing the whole mesh (stopping at the first with a
    score of at least :data:`CONFIDENT_FRONT`), then (when no face was found in
    any) framing the top eighth of the mesh along the view's up: a head on a whole body is too
    small otherwise (a whole body is stored upright); then the 18 :data:`OTHER_AXIS_VIEWS`
    framing the whole mesh.
    """
    from stimulus_engine.morphpca.keypoints import detect_landmarks_scored

    v = np.asarray(mesh.vertices, dtype=np.float64)
    for views, zoom in ((AXIS_VIEWS, False), (AXIS_VIEWS, True), (OTHER_AXIS_VIEWS, False)):
        best: tuple[float, str, np.ndarray, float] | None = None
        for key, (d, up) in views.items():
            c, r = centre, radius
            if zoom:
                height = v @ np.asarray(up, float)
                extent = float(height.max() - height.min())
                c = centre + np.asarray(up, float) * (height.max() - extent / 16 - centre @ np.asarray(up, float))
                r = extent / 12
            view = _View(mesh, c, r, np.asarray(d, float), np.asarray(up, float), size)
            try:
                _, score = detect_landmarks_scored(view.image, name)
            except AppealInputError:
                continue
            if best is None or score > best[0]:
                best = (score, key, c, r)
            if score >= CONFIDENT_FRONT:  # a frontal face: no other axis view shows one
                break
        if best is not None:
            d, up = views[best[1]]
            return best[1], np.asarray(d, float), np.asarray(up, float), best[2], best[3]
    raise AppealInputError(f"{name}: landmarks: auto: no face found in 24 renders along the mesh's axes "
                           "(expected a face mesh upright along an axis; give the landmarks by hand instead)")


def detect_mesh_landmarks(mesh: trimesh.Trimesh, *, name: str = "mesh", size: int = 640, yaw_deg: float = 15.0,
                          pitch_deg: float = 10.0, front: str | None = None) -> MeshLandmarks:
    """The 68 iBUG landmarks of a face mesh, detected in renders and lifted onto the surface.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        A face or head mesh (textured or not), any orientation.
    name : str
        Names the mesh in errors.
    size : int
        Render size in pixels (square).
    yaw_deg, pitch_deg : float
        The side views' angles around the front.
    front : str, optional
        A key of :data:`ALL_AXIS_VIEWS` to use as the front instead of searching for it.

    Returns
    -------
    MeshLandmarks

    Raises
    ------
    AppealInputError
        When no face is found (one line naming the mesh).
    """
    drawn = _drawable(mesh)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, radius, diag = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2, float(np.linalg.norm(hi - lo))
    if front is None:
        front, direction, up, centre, radius = _find_front(drawn, centre, radius, size // 2, name)
    else:
        if front not in ALL_AXIS_VIEWS:
            raise AppealInputError(f"{name}: landmarks: front: expected one of {', '.join(AXIS_VIEWS)} or "
                                   f"'+x/up+z'-like (got {front!r})")
        direction, up = (np.asarray(x, float) for x in ALL_AXIS_VIEWS[front])
    stack, scores = lift_views(drawn, centre, radius, direction, up, name=name, size=size, yaw_deg=yaw_deg,
                               pitch_deg=pitch_deg)
    if not len(stack):
        raise AppealInputError(f"{name}: landmarks: auto: no face found around the {front} view "
                               "(expected a face mesh; give the landmarks by hand instead)")
    missing = np.flatnonzero(np.isnan(stack[..., 0]).all(axis=0)).tolist()
    if missing:
        raise AppealInputError(f"{name}: landmarks: auto: points {missing} not on the surface in any view "
                               "(give them by hand)")
    combined, confidence = combine_views(stack, diag)
    surface = closest_surface_points(mesh, combined)[0]
    return MeshLandmarks(surface.positions(v), surface, confidence, front, len(stack), scores)


def merge_landmarks(auto: MeshLandmarks, given: Mapping[int, np.ndarray], mesh: trimesh.Trimesh) -> MeshLandmarks:
    """``auto`` with the points in ``given`` (iBUG index -> 3D point) put in their place.

    Given points are snapped to the surface and get confidence 1.
    """
    if not given:
        return auto
    bad = [k for k in given if not (isinstance(k, (int, np.integer)) and 0 <= int(k) < 68)]
    if bad:
        raise AppealInputError(f"landmarks: expected iBUG indices 0-67 (got {bad})")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    idx = np.array(sorted(int(k) for k in given))
    fresh = closest_surface_points(mesh, np.array([given[k] for k in idx], dtype=np.float64))[0]
    verts, weights = auto.surface.vertices.copy(), auto.surface.weights.copy()
    verts[idx], weights[idx] = fresh.vertices, fresh.weights
    surface = SurfacePoints(verts, weights)
    confidence = auto.confidence.copy()
    confidence[idx] = 1.0
    return MeshLandmarks(surface.positions(v), surface, confidence, auto.front, auto.views, auto.scores)
