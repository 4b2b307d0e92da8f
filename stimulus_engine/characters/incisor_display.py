"""The upper incisors shown between parted lips, as a person's are.

A scan's mouth inside is the rig's (teeth, gums, tongue), carried by the rig's jaw and upper
face, while the scan's lips are its own: where the rig's expression lowers the upper lip further
than the rig's teeth fit (james's surprise: his upper lip ends 2 mm below his incisors' edges
with the jaw dropped), the open mouth shows no tooth at all, only the back of the mouth. At rest
with the lips apart, a man shows about 1.9 mm of his upper incisors and a woman 3.4 mm (Vig &
Brundo 1978). :func:`show_upper_incisors` lowers the upper teeth, only where the lips are parted
and the teeth are hidden, until their edges show by that much (less between barely parted lips);
the teeth's roots are long enough to stay in the gums.
"""

from __future__ import annotations

import numpy as np

__all__ = ["INCISOR_DISPLAY_IOD", "show_upper_incisors", "upper_teeth"]

#: The upper incisors' edges show this far below the upper lip between parted lips (inter-ocular
#: distances; 1.9 mm of a 63 mm eye distance: Vig & Brundo 1978, men at rest) ...
INCISOR_DISPLAY_IOD = 0.03
#: ... or this share of the lips' opening where that is less (lips barely apart).
DISPLAY_SHARE = 0.15
#: Lips are parted where their opening at the midline exceeds this (inter-ocular distances;
#: about 3 mm); closed or barely parted, nothing moves.
OPEN_IOD = 0.05
#: Lips and incisors are measured within this share of the mouth's width either side of its centre.
MIDLINE_SHARE = 0.15


def upper_teeth(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...]) -> np.ndarray:
    """Vertices of the upper teeth: each tooth (a connected piece of the ``teeth`` part) whose
    centre lies above the mean of all the teeth's centres (in the neutral ``vertices``; the two
    arches' roots point away from each other, so the crowns' overlap does not matter)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if "teeth" not in part_names:
        return np.zeros(0, np.int64)
    tf = faces[face_part == part_names.index("teeth")]
    if not len(tf):  # a part list that names teeth the mesh has none of (a procedural head)
        return np.zeros(0, np.int64)
    n = len(vertices)
    graph = coo_matrix((np.ones(tf.size), (tf.ravel(), np.roll(tf, 1, axis=1).ravel())), shape=(n, n))
    label = connected_components(graph, directed=False)[1]
    teeth = np.unique(tf)
    pieces, piece = np.unique(label[teeth], return_inverse=True)
    centre_y = np.bincount(piece, vertices[teeth, 1]) / np.bincount(piece)
    return teeth[centre_y[piece] > centre_y.mean()]


def show_upper_incisors(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...],
                        upper: np.ndarray, mouth_left: np.ndarray, mouth_right: np.ndarray,
                        iod: float) -> np.ndarray:
    """``vertices`` with the ``upper`` teeth lowered (-y) until their edges show below the upper lip.

    The lips are the ``skin`` part's border around the mouth (a scan cut along its lip line);
    at the mouth's midline, the upper lip's lowest border point and the lower lip's highest
    give the opening. Where it is open (more than :data:`OPEN_IOD`) and the incisors' lowest point lies above the upper lip
    less :data:`INCISOR_DISPLAY_IOD` (or :data:`DISPLAY_SHARE` of the opening, if less), the
    upper teeth move down by the difference; otherwise nothing moves.

    Parameters
    ----------
    vertices : (N, 3) array
        A pose of a drawn topology (+y up).
    faces, face_part, part_names
        Its triangles and their parts.
    upper : int array
        The upper teeth's vertices (:func:`upper_teeth`).
    mouth_left, mouth_right : (3,) arrays
        The mouth's corners in this pose.
    iod : float
        The inter-ocular distance.

    Returns
    -------
    (N, 3) array
        A copy.
    """
    from stimulus_engine.geometry.mesh_ops import boundary_vertex_mask

    v = np.array(vertices, np.float64, copy=True)
    if not len(upper) or "skin" not in part_names:
        return v
    centre, width = (mouth_left + mouth_right) / 2, float(np.linalg.norm(mouth_left - mouth_right))
    skin = faces[face_part == part_names.index("skin")]
    border = np.flatnonzero(boundary_vertex_mask(skin, len(v)))
    rim = border[(np.abs(v[border, 0] - centre[0]) < MIDLINE_SHARE * width)
                 & (np.linalg.norm(v[border] - centre, axis=1) < 0.5 * width)]
    incisors = upper[np.abs(v[upper, 0] - centre[0]) < MIDLINE_SHARE * width]
    if len(rim) < 2 or not len(incisors) or np.ptp(v[rim, 1]) <= OPEN_IOD * iod:
        return v
    y = v[rim, 1]
    split = (y.max() + y.min()) / 2
    top, bottom = y[y > split].min(), y[y <= split].max()
    opening = top - bottom
    if opening <= OPEN_IOD * iod:
        return v
    edge = top - min(INCISOR_DISPLAY_IOD * iod, DISPLAY_SHARE * opening)
    lowest = v[incisors, 1].min()
    if lowest > edge:
        v[upper, 1] -= lowest - edge
    return v
