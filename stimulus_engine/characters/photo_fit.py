"""The ICT Face Model fitted to one photograph's landmarks (issue 49): pure functions.

A face model with identity components ``B`` (the ICT model's 100 principal components, each a
delta from the mean face ``m`` with unit variance: the toolkit's ``randomize_identity`` draws
their weights from N(0, 1)) and expression shapes ``E`` (ARKit/FACS deltas, weights in [0, 1])
gives every landmark vertex ``X_i = m_i + B_i a + E_i b``. A frontal photograph seen from a
metre or more is modelled by a *scaled orthographic* camera ``x_i = s R X_i + t`` (the first two
rows of a rotation, image y down): the perspective of a portrait lens moves the 68 points by
well under a pixel per cent of the eye distance, and the orthographic camera keeps both steps of
the fit linear.

:func:`fit_landmarks` alternates the two linear problems, as the eos and 3DDFA fitters do
(Huber et al. 2016; Zhu et al. 2016):

1. **camera** given the shape: an affine camera by least squares, made the nearest scaled
   rotation (SVD), then refined by orthographic Procrustes with the depths filled in from the
   current rotation (:func:`fit_camera`);
2. **shape** given the camera: the identity and expression weights by bounded, regularised
   least squares (:func:`fit_shape`) — the landmarks' residuals in units of their noise
   (``noise`` times the eye distance: dlib's points scatter by 2-4 % of it on frontal faces)
   plus the model's own prior, ``|a|^2`` (unit-variance components) and ``prior_expression |b|^2``.

The jaw-line points (iBUG 0-16) lie on the face's silhouette, which slides over the surface as
the head turns; they count half (``contour_weight``). Depth is only seen through the model: the
prior picks the most likely depth for the drawn outline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OrthoCamera", "PhotoFit", "fit_camera", "fit_landmarks", "fit_shape", "landmark_weights"]


@dataclass(frozen=True)
class OrthoCamera:
    """A scaled orthographic camera: image point ``(u, v) = s (R X)[:2] * (1, -1) + t``, or, with a
    ``centre``, a pinhole there that agrees with it at depth ``reference`` (:meth:`perspective`).

    Attributes
    ----------
    scale : float
        Pixels per model unit (centimetres for the ICT model).
    rotation : (3, 3) array
        Model frame to camera frame (camera +z toward the viewer, +y up).
    translation : (2,) array
        Image position (pixels, y down) of the model's origin.
    centre : (3,) array or None
        A pinhole's position (model frame); None: orthographic.
    reference : float
        The camera depth at which the pinhole and the orthographic camera agree.
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    centre: np.ndarray | None = None
    reference: float = 0.0

    def perspective(self, centre: np.ndarray, reference: float) -> OrthoCamera:
        """The same camera as a pinhole at ``centre`` (model frame, on the viewer's side): points at
        camera depth ``reference`` project as before, nearer ones larger, farther ones smaller —
        the perspective of a renderer's camera placed there, so an image laid on the face through
        this camera is seen undistorted from that camera."""
        return OrthoCamera(self.scale, self.rotation, self.translation, np.asarray(centre, np.float64), float(reference))

    def _flatten(self, points: np.ndarray) -> np.ndarray:
        """Points moved along their rays from ``centre`` to the reference depth (orthographic there)."""
        if self.centre is None:
            return points
        view = self.rotation[2]
        v = points - self.centre
        along = v @ view  # negative: in front of the camera
        lateral = v - along[:, None] * view
        ref = (self.reference - self.centre @ view)
        return self.centre + ref * view + lateral * (ref / along)[:, None]

    def project(self, points: np.ndarray) -> np.ndarray:
        """Image points ``(n, 2)`` (x right, y down) of model points ``(n, 3)``."""
        p = self._flatten(np.asarray(points, np.float64)) @ self.rotation.T
        return np.column_stack([self.scale * p[:, 0], -self.scale * p[:, 1]]) + self.translation

    def depth(self, points: np.ndarray) -> np.ndarray:
        """Distance toward the viewer (model units; larger is nearer the camera)."""
        return np.asarray(points, np.float64) @ self.rotation[2]

    def unproject(self, pixels: np.ndarray, depth: float) -> np.ndarray:
        """Model points ``(n, 3)`` that project to ``pixels`` at camera depth ``depth``."""
        xy = (np.asarray(pixels, np.float64) - self.translation) / self.scale
        ref = self.reference if self.centre is not None else float(depth)
        flat = np.column_stack([xy[:, 0], -xy[:, 1], np.full(len(xy), ref)]) @ self.rotation
        if self.centre is None:
            return flat
        view = self.rotation[2]
        c = self.centre
        lateral = (flat - c) - ((flat - c) @ view)[:, None] * view
        return c + (depth - c @ view) * view + lateral * ((depth - c @ view) / (ref - c @ view))

    @property
    def view_direction(self) -> np.ndarray:
        """Unit vector in the model frame from the face toward the camera."""
        return self.rotation[2].copy()

    @property
    def yaw_degrees(self) -> float:
        """Head turn about the vertical axis (0: frontal)."""
        return float(np.degrees(np.arctan2(self.rotation[2, 0], self.rotation[2, 2])))

    @property
    def pitch_degrees(self) -> float:
        """Head tilt up or down (0: level)."""
        return float(np.degrees(np.arcsin(np.clip(self.rotation[2, 1], -1.0, 1.0))))


@dataclass(frozen=True)
class PhotoFit:
    """A fit of the face model to one photograph's landmarks.

    Attributes
    ----------
    identity : (K,) array
        Weights of the identity components.
    expression : (E,) array
        Weights of the expression shapes, in [0, 1].
    camera : OrthoCamera
    residuals : (n,) array
        Each landmark's distance from its fitted projection, in pixels.
    eye_distance : float
        Distance between the eye centres in the photograph, pixels.
    """

    identity: np.ndarray
    expression: np.ndarray
    camera: OrthoCamera
    residuals: np.ndarray
    eye_distance: float

    @property
    def rms(self) -> float:
        """Root-mean-square residual as a share of the eye distance."""
        return float(np.sqrt(np.mean(self.residuals ** 2)) / self.eye_distance)


def landmark_weights(n: int = 68, contour_weight: float = 0.5) -> np.ndarray:
    """Per-landmark weights for iBUG's 68 points: the jaw line (0-16) at ``contour_weight``."""
    w = np.ones(n)
    if n == 68:
        w[:17] = contour_weight
    return w


def _nearest_rotation(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def fit_camera(model: np.ndarray, image: np.ndarray, weights: np.ndarray | None = None,
               iterations: int = 4) -> OrthoCamera:
    """The scaled orthographic camera taking ``model`` points ``(n, 3)`` nearest to ``image``
    points ``(n, 2)`` (weighted least squares).

    An affine camera by least squares gives the first guess (its 2 x 3 part made the nearest
    scaled rotation); each iteration then fills in every point's depth from the current rotation
    and solves the 3D similarity in closed form (Umeyama), which keeps the rotation proper.
    """
    X = np.asarray(model, np.float64)
    x = np.asarray(image, np.float64) * [1.0, -1.0]  # y up, as the model
    w = np.ones(len(X)) if weights is None else np.asarray(weights, np.float64)
    sw = np.sqrt(w)[:, None]
    h = np.column_stack([X, np.ones(len(X))])
    A = np.linalg.lstsq(h * sw, x * sw, rcond=None)[0]  # (4, 2)
    M = A[:3].T
    u, sv, vt = np.linalg.svd(M, full_matrices=False)
    r2 = u @ vt
    R = np.vstack([r2, np.cross(r2[0], r2[1])])
    if np.linalg.det(R) < 0:
        R[2] *= -1
    s = float(sv.mean())
    wn = w / w.sum()
    for _ in range(iterations):
        cx, cX = wn @ x, wn @ X
        Xc, xc = X - cX, x - cx
        z = Xc @ R[2]
        target = np.column_stack([xc / s, z])  # camera-frame points (model units)
        H = (Xc * wn[:, None]).T @ target
        R = _nearest_rotation(H.T)
        p = Xc @ R[:2].T
        s = float((wn * np.einsum("ij,ij->i", p, xc)).sum() / (wn * np.einsum("ij,ij->i", p, p)).sum())
    t = (wn @ x) - s * (wn @ X) @ R[:2].T
    return OrthoCamera(s, R, np.array([t[0], -t[1]]))


def fit_shape(camera: OrthoCamera, image: np.ndarray, mean: np.ndarray, identity_basis: np.ndarray,
              expression_basis: np.ndarray, *, sigma: float, weights: np.ndarray | None = None,
              prior_expression: float = 1.0, identity_bound: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """Identity and expression weights that bring the landmarks nearest ``image`` under ``camera``.

    Minimises ``sum_i w_i |P X_i - x_i|^2 / sigma^2 + |a|^2 + prior_expression |b|^2`` with
    ``|a_k| <= identity_bound`` and ``0 <= b_j <= 1`` (bounded linear least squares).

    Parameters
    ----------
    camera : OrthoCamera
    image : (n, 2) array
        Landmarks in the photograph (pixels).
    mean : (n, 3) array
        The model's mean face at the landmark vertices.
    identity_basis : (K, n, 3) array
        Identity components at the landmark vertices.
    expression_basis : (E, n, 3) array
        Expression deltas at the landmark vertices (E may be 0).
    sigma : float
        Landmark noise in pixels.
    """
    from scipy.optimize import lsq_linear

    n = len(mean)
    w = np.ones(n) if weights is None else np.asarray(weights, np.float64)
    P = camera.scale * camera.rotation[:2] * np.array([[1.0], [-1.0]])  # (2, 3), image y down
    basis = np.concatenate([identity_basis, expression_basis], axis=0)  # (K+E, n, 3)
    k, e = len(identity_basis), len(expression_basis)
    A = np.einsum("cd,knd->nck", P, basis).reshape(2 * n, k + e)
    b = (np.asarray(image, np.float64) - camera.translation - mean @ P.T).reshape(2 * n)
    rw = np.repeat(np.sqrt(w), 2) / sigma
    prior = np.concatenate([np.ones(k), np.full(e, np.sqrt(prior_expression))])
    A_all = np.vstack([A * rw[:, None], np.diag(prior)])
    b_all = np.concatenate([b * rw, np.zeros(k + e)])
    lo = np.concatenate([np.full(k, -identity_bound), np.zeros(e)])
    hi = np.concatenate([np.full(k, identity_bound), np.ones(e)])
    c = lsq_linear(A_all, b_all, bounds=(lo, hi), method="bvls" if k + e <= 64 else "trf", lsmr_tol="auto").x
    return c[:k], c[k:]


def fit_landmarks(image: np.ndarray, mean: np.ndarray, identity_basis: np.ndarray,
                  expression_basis: np.ndarray | None = None, *, noise: float = 0.03,
                  contour_weight: float = 0.5, prior_expression: float = 1.0,
                  iterations: int = 8) -> PhotoFit:
    """Fit the face model and a scaled orthographic camera to one photograph's 68 landmarks.

    Parameters
    ----------
    image : (68, 2) array
        iBUG/dlib landmarks in the photograph (pixels, y down).
    mean, identity_basis, expression_basis
        The model at its 68 landmark vertices (see :func:`fit_shape`).
    noise : float
        Landmark noise as a share of the eye distance (default 3 %).
    contour_weight : float
        Weight of the jaw line's points (they slide with the silhouette).
    prior_expression : float
        Weight of the expression prior (larger: a neutral face is assumed more strongly).
    iterations : int
        Camera-then-shape rounds (the fit settles in 4-6).

    Returns
    -------
    PhotoFit
    """
    x = np.asarray(image, np.float64)
    mean = np.asarray(mean, np.float64)
    B = np.asarray(identity_basis, np.float64)
    E = np.zeros((0, *mean.shape)) if expression_basis is None else np.asarray(expression_basis, np.float64)
    if x.shape != (len(mean), 2):
        raise ValueError(f"expected {len(mean)} image points, got {x.shape}")
    w = landmark_weights(len(mean), contour_weight)
    iod = float(np.linalg.norm(x[36:42].mean(axis=0) - x[42:48].mean(axis=0))) if len(x) == 68 else \
        float(np.ptp(x[:, 0]) / 2)
    a, b = np.zeros(len(B)), np.zeros(len(E))
    shape = mean
    for _ in range(iterations):
        cam = fit_camera(shape, x, w)
        a, b = fit_shape(cam, x, mean, B, E, sigma=noise * iod, weights=w, prior_expression=prior_expression)
        shape = mean + np.tensordot(a, B, 1) + np.tensordot(b, E, 1)
    cam = fit_camera(shape, x, w)
    res = np.linalg.norm(cam.project(shape) - x, axis=1)
    return PhotoFit(a, b, cam, res, iod)
