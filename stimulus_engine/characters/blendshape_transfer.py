"""Blendshape transfer with range-of-motion alignment (thesis ch. 4, §4.3, Eqs 4.4–4.13).

A rig's blendshapes carried onto another neutral face (an actor, a stylised shape, a scan) by
three methods:

- ``deformation_transfer`` — each blendshape's deformation gradients applied to the target's
  triangles (Sumner & Popović 2004; :func:`~stimulus_engine.characters.expressions.deformation_transfer`).
- ``rbf`` — RBF proportion matching (Orvalho et al. 2008, Seol et al. 2012): a thin-plate spline
  ``f`` maps the rig's neutral markers onto the target's, and a blendshape becomes
  ``f(v₀ + δv_k) − f(v₀)``.
- ``aligned`` — the thesis's method. Both of the above keep an expression's local shape but copy
  the rig's *range of motion* in the target's proportions: on a face with other proportions an
  expression gets weaker or stronger (Figs 4.2/4.3). The aligned transfer starts from the RBF
  guesses ``δg_k`` and moves the sparse (marker) blendshapes ``δb_k`` towards the frames of a
  training sequence of the target that resemble them (:mod:`~stimulus_engine.characters.motion_similarity`):

  ``E_Align = E_Match + α E_Mesh + β E_CEG`` (Eq. 4.4, α = 0.01, β = 0.1), with

  - ``E_Match = Σ_k Σ_m ψ_k^m ‖δb_k^m − Σ_f ρ̂_kf δa_f^m‖²`` over the key frames (Eq. 4.10;
    ψ_k the blendshape's soft support mask ``|δs_k^m| / max_m |δs_k^m|``),
  - ``E_Mesh = 1/M Σ_k ‖L (δb_k − δg_k)‖²`` with ``L`` the cotangent Laplacian of the marker
    mesh, lid and lip contact edges included (Eq. 4.11; :mod:`~stimulus_engine.characters.markers`),
  - ``E_CEG = 1/M Σ_k ‖Δ(δb_k − δs_k)‖²`` with ``Δ`` the signed graph Laplacian of the
    Cross-Expression Graph whose edge weights are the blendshapes' correlations (Eqs 4.12–4.13).

  Three changes from Eq. 4.10 as printed, each measured on the synthetic ground truth of
  ``tests/test_blendshape_transfer.py`` (an ICT identity whose blendshapes are scaled by known
  factors 0.5–2; weights recovered by :func:`~stimulus_engine.characters.retarget.retarget_frames`):

  1. **The mask weighs the match instead of scaling its target.** ``‖δb_k − diag(ψ_k) δa_f‖²``
     shrinks every marker that moves less than the blendshape's largest by ψ: even an actor
     identical to the rig does not get the rig's blendshapes back (weight RMSE 0.96 against
     0.08 for deformation transfer). Weighting the squared error by ψ keeps the thesis's
     purpose (a frame with both eyes closed does not pull the left blink's right-eye markers,
     Fig. 4.9) and returns the rig on the rig.
  2. **Each blendshape is matched to a weighted mean of its most similar key frames**
     (``ρ̂_kf = ρ̃_kf / Σ_f ρ̃_kf`` over the key frames within 3 % of its best one). With the
     thesis's ``1/F Σ_f ρ̃_kf`` every blendshape is pulled towards every frame it faintly
     resembles (a left smile towards the right dimple), and the recovered scale factors did
     not correlate with the true ones (r = −0.17).
  3. **α = β = 10⁻⁴.** After (2) the match of a blendshape weighs about F times more than in the
     thesis, and E_Mesh pulls towards the *unscaled* guess's Laplacian: with α = 0.01 and
     β = 0.1 the weights came out hardly better than by the better baseline (−7 … +14 % lower
     RMSE on the four actors of the test); at 10⁻⁴ the two constraints still fix the markers the
     match leaves free (with α = 0 they are ill-determined) and the RMSE is 43–68 % lower than
     the better of RBF and deformation transfer.

  Two more, from a noisy performance (issue 50: synthetic actors whose ranges differ from the rig's by
  0.6–1.6×, 0.2 mm marker noise, a warm-up whose ramps overlap; ``benchmarks/retarget_actors.py``):

  4. **Frames are matched by what explains them, at their apex** (``matching="fit"``). Eqs 4.5–4.8
     compare directions only: a frame at a fifth of a blendshape's range looks as similar as its
     apex, noise lowers the cosine of a small blendshape's own frames below that of a larger
     blendshape's (a smile frame "resembled" mouthDimple more than the dimple's own), and a cosine
     cannot tell which of two overlapping ramps a frame shows. Here every training frame is first
     explained by the guesses (non-negative retargeting, :func:`~stimulus_engine.characters.retarget.retarget_frames`):
     a frame shows blendshape k when k makes at least :data:`ALIGN_PURITY` of its fitted motion, and
     k's target is the mean of those frames where k's weight is within :data:`ALIGN_APEX` of its
     largest (the apex of its range of motion, weight 1 by the warm-up's definition), minus the other
     blendshapes' fitted motion in them. A blendshape no frame shows keeps its guess. With the thesis's
     similarity matching the weight RMS was 0.11–0.12 against 0.07–0.08 for RBF; with this, 0.044–0.05.
     ``matching="similarity"`` keeps Eqs 4.5–4.10 (with change 2).
  5. **The correction is bounded where the frames carry no evidence** (:data:`ALIGN_EVIDENCE`). Where a
     blendshape hardly moves a marker, the matched frames there carry only noise (0.5 mm of error
     against 0.18 mm of motion), which the mask only weighs and E_Mesh at α = 10⁻⁴ cannot hold back:
     the correction from the guess is scaled by ``min(1, |δg| / 10σ)``, σ the frames' noise (estimated
     from their second differences, :func:`frame_noise`), so such markers stay near the RBF guess
     and a clean capture is aligned everywhere (10σ: weight RMS where ranges differ 0.045–0.055 on three
     actors, against 0.049–0.068 at 3σ and 0.049–0.053 at 25σ).

  The three energies are quadratic and separable in x, y and z: one sparse (MK × MK) system,
  factorised once and solved for the three coordinates (§4.3.6). The dense blendshapes (every
  vertex, not only the markers) are deformation transfer's, each scaled vertex by vertex by a
  smooth gain: how much longer the aligned sparse blendshape is than deformation transfer's at
  each marker, spread by a thin-plate spline (:func:`densify`). Scaling keeps the local shape
  (a vector correction folded the tiny triangles where the lips meet), and a vertex the rig's
  blendshape does not move (the eyeballs, the back of the head) stays where it is.

For a stylised shape there is no captured actor; its training sequence is the rig's own range of
motion (:func:`range_of_motion`: each blendshape alone at its apex, noise-free, so each frame is
matched by similarity, its own frame at similarity 1, and nothing is bounded by noise)
measured on the rig's markers and scaled by the ratio of the two faces' lengths (forehead to
chin, the length the grid frames every face by): the target is asked to move as far, in units of
its own face, as the rig does. That is what makes an anger at the cartoon level the same anger
as at the realistic level.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.interpolate import RBFInterpolator

from stimulus_engine.characters.markers import marker_laplacian, marker_mesh, marker_vertices
from stimulus_engine.characters.motion_similarity import CONTRAST_STEEPNESS, correlations, key_frames, similarity
from stimulus_engine.characters.rig import FaceRig

__all__ = [
    "ALIGN_ALPHA",
    "ALIGN_APEX",
    "ALIGN_BETA",
    "ALIGN_EVIDENCE",
    "ALIGN_MATCHING",
    "ALIGN_PURITY",
    "ALIGN_SELECTIVITY",
    "THESIS_ALPHA",
    "THESIS_BETA",
    "TRANSFER_METHODS",
    "AlignResult",
    "align_blendshapes",
    "cross_expression_laplacian",
    "densify",
    "face_length",
    "frame_noise",
    "range_of_motion",
    "rbf_warp",
    "soft_masks",
    "transfer_blendshapes",
    "warp_deltas",
]

#: Weights of the geometric and cross-expression constraints (Eq. 4.4; the thesis's "α = 0.01
#: and β = 0.1 in all shown examples" weigh a match normalised differently: module notes).
ALIGN_ALPHA = 1e-4
ALIGN_BETA = 1e-4
#: The thesis's values, kept for comparison (``alpha=THESIS_ALPHA, beta=THESIS_BETA``).
THESIS_ALPHA = 0.01
THESIS_BETA = 0.1
#: Key frames matched to a blendshape: those within 3 % of its most similar one (``matching="similarity"``).
ALIGN_SELECTIVITY = 0.97
#: How a blendshape finds its frames in the training sequence (module notes, 4).
ALIGN_MATCHING = "fit"
#: ``matching="fit"``: a frame shows blendshape k when k makes at least this share of the frame's fitted motion,
#: and is its apex when k's weight there is at least ``ALIGN_APEX`` of k's largest among those frames.
ALIGN_PURITY = 0.4
ALIGN_APEX = 0.8
#: Where the guess moves a marker by less than this many times the frames' noise, the training frames carry no
#: evidence there: the aligned correction is scaled by ``|δg| / (ALIGN_EVIDENCE σ)`` (module notes, 5).
ALIGN_EVIDENCE = 10.0
#: The methods :func:`transfer_blendshapes` knows.
TRANSFER_METHODS = ("aligned", "rbf", "deformation_transfer")
#: Smoothing of the thin-plate spline of the markers' gains (0 interpolates them exactly).
GAIN_SMOOTHING = 0.0
#: A marker whose guess moves less than this fraction of the blendshape's largest motion takes
#: the blendshape's overall gain (:func:`densify`).
_SUPPORT_FRACTION = 0.05


# --------------------------------------------------------------------------------------------
# RBF proportion matching
# --------------------------------------------------------------------------------------------


def rbf_warp(source: np.ndarray, target: np.ndarray) -> RBFInterpolator:
    """The thin-plate spline (with its affine part) that maps ``source`` points onto ``target``."""
    return RBFInterpolator(np.asarray(source, np.float64), np.asarray(target, np.float64),
                           kernel="thin_plate_spline", degree=1)


def warp_deltas(warp: RBFInterpolator, neutral: np.ndarray, deltas: np.ndarray) -> np.ndarray:
    """``f(v₀ + δ_k) − f(v₀)`` for each delta of ``deltas`` (K, P, 3) at the points ``neutral`` (P, 3)."""
    neutral = np.asarray(neutral, np.float64)
    deltas = np.asarray(deltas, np.float64)
    k, p, _ = deltas.shape
    moved = np.abs(deltas).max(axis=(0, 2)) > 0
    out = np.zeros_like(deltas)
    if not moved.any():
        return out
    pts = np.concatenate([neutral[moved], (neutral[moved][None] + deltas[:, moved]).reshape(-1, 3)])
    f = warp(pts)
    n = int(moved.sum())
    out[:, moved] = f[n:].reshape(k, n, 3) - f[:n][None]
    return out


# --------------------------------------------------------------------------------------------
# E_Align
# --------------------------------------------------------------------------------------------


def soft_masks(blendshapes: np.ndarray) -> np.ndarray:
    """ψ_k (K, M): each marker's displacement over the blendshape's largest (thesis §4.3.3)."""
    n = np.linalg.norm(np.asarray(blendshapes, np.float64), axis=2)
    top = n.max(axis=1, keepdims=True)
    return np.divide(n, top, out=np.zeros_like(n), where=top > 0)


def cross_expression_laplacian(blendshapes: np.ndarray) -> np.ndarray:
    """The signed graph Laplacian of the Cross-Expression Graph (Eq. 4.12), K × K.

    Row k: ``Δ(x)_k = Σ_{i≠k} ρ_ki (x_i − x_k) / Σ_{i≠k} |ρ_ki|`` with ``ρ`` the blendshapes'
    signed correlations (Eq. 4.5).
    """
    rho = correlations(blendshapes, blendshapes)
    np.fill_diagonal(rho, 0.0)
    norm = np.abs(rho).sum(axis=1, keepdims=True)
    g = np.divide(rho, norm, out=np.zeros_like(rho), where=norm > 0)
    return g - np.diag(g.sum(axis=1))


@dataclass
class AlignResult:
    """The sparse aligned blendshapes and what went into them.

    Attributes
    ----------
    blendshapes : (K, M, 3) array
        The personalised sparse delta blendshapes ``δb_k``.
    initial : (K, M, 3) array
        The RBF guesses ``δg_k`` they started from.
    key_frames : (F',) int array
        The training frames E_Match used (§4.3.2).
    similarity : (K, F') array
        ``ρ̂_kf``: each frame's weight in each blendshape's target (Eq. 4.8 normalised; with
        ``matching="fit"``, equal weights over the blendshape's apex frames).
    energies : dict
        ``match``, ``mesh``, ``ceg`` and ``total`` at the solution (weighted as in Eq. 4.4).
    """

    blendshapes: np.ndarray
    initial: np.ndarray
    key_frames: np.ndarray
    similarity: np.ndarray
    energies: dict = field(default_factory=dict)


def align_blendshapes(rig_blendshapes: np.ndarray, frames: np.ndarray, initial: np.ndarray,
                      actor_markers: np.ndarray, *, alpha: float = ALIGN_ALPHA, beta: float = ALIGN_BETA,
                      r: float = CONTRAST_STEEPNESS, selectivity: float = ALIGN_SELECTIVITY,
                      triangles: np.ndarray | None = None, matching: str = ALIGN_MATCHING,
                      purity: float = ALIGN_PURITY, apex: float = ALIGN_APEX,
                      noise: float | None = None, evidence: float = ALIGN_EVIDENCE) -> AlignResult:
    """Minimise ``E_Align`` (Eq. 4.4) for the personalised sparse blendshapes.

    Parameters
    ----------
    rig_blendshapes : (K, M, 3) array
        The rig's sparse delta blendshapes ``δs_k`` (its blendshapes at the markers).
    frames : (F, M, 3) array
        The actor's training sequence as marker displacements from its neutral, ``δa_f``.
    initial : (K, M, 3) array
        The initial guesses ``δg_k`` (RBF proportion matching).
    actor_markers : (M, 3) array
        The actor's neutral marker positions (the marker mesh is built on them).
    alpha, beta : float
        Weights of E_Mesh and E_CEG (see the module notes for why not the thesis's 0.01 and 0.1).
    r : float
        Steepness of the contrast sigmoid (Eq. 4.7).
    selectivity : float
        A blendshape is matched only to the key frames whose similarity ``ρ̃_kf`` is at least this
        fraction of its best one (0: every key frame, as Eq. 4.10 reads).
    triangles : (T, 3) int array, optional
        The marker mesh (default :func:`~stimulus_engine.characters.markers.marker_mesh`).
    matching : {"fit", "similarity"}
        How each blendshape finds its training frames: explained by the guesses, at the apex
        (module notes, 4), or by Eqs 4.5–4.10 (``r``, ``selectivity``).
    purity, apex : float
        ``matching="fit"``: a frame's share of fitted motion that makes it show a blendshape, and
        the fraction of the largest weight that makes it the blendshape's apex.
    noise : float, optional
        Standard deviation of the frames' marker noise (default: estimated from the frames,
        :func:`frame_noise`; 0 for noise-free frames: nothing is bounded).
    evidence : float
        The correction from the guess is scaled by ``min(1, |δg| / (evidence · noise))`` per
        marker (module notes, 5).

    Returns
    -------
    AlignResult
    """
    s = np.asarray(rig_blendshapes, np.float64)
    a = np.asarray(frames, np.float64)
    g = np.asarray(initial, np.float64)
    k, m, _ = s.shape
    if a.ndim != 3 or a.shape[1:] != (m, 3) or g.shape != s.shape:
        raise ValueError(f"shapes do not agree: blendshapes {s.shape}, frames {a.shape}, initial {g.shape}")
    if matching not in ("fit", "similarity"):
        raise ValueError(f"matching '{matching}': expected fit or similarity")
    psi = soft_masks(s)  # (K, M): each marker's weight in the match
    if matching == "fit":
        keys, rho, target, shown = _apex_targets(a, g, purity, apex)
        psi = psi * shown[:, None]  # a blendshape no frame shows keeps its guess
    else:
        keys = key_frames(similarity(s, a, r))
        a = a[keys]
        rho = similarity(s, a, r)  # (K, F')
        rho = np.where(rho >= selectivity * rho.max(axis=1, keepdims=True), rho, 0.0)
        total = rho.sum(axis=1, keepdims=True)
        rho = np.divide(rho, total, out=np.zeros_like(rho), where=total > 0)  # a weighted mean per blendshape
        target = np.einsum("kf,fmc->kmc", rho, a)
    tri = marker_mesh(actor_markers) if triangles is None else triangles
    lap = marker_laplacian(actor_markers, tri)
    mesh = (lap.T @ lap) * (alpha / m)
    ceg_g = cross_expression_laplacian(s)
    ceg = sp.kron(sp.csr_matrix(ceg_g.T @ ceg_g), sp.identity(m), format="csr") * (beta / m)
    hess = (sp.diags(psi.ravel()) + sp.kron(sp.identity(k), mesh, format="csr") + ceg).tocsc()
    ridge = 1e-10 * float(hess.diagonal().mean())  # pins a marker nothing else determines to its guess
    hess = hess + ridge * sp.identity(k * m, format="csc")
    gv, sv = g.reshape(k * m, 3), s.reshape(k * m, 3)
    rhs = (psi[:, :, None] * target).reshape(k * m, 3) + sp.kron(sp.identity(k), mesh) @ gv + ceg @ sv + ridge * gv
    solve = spla.factorized(hess)
    b = np.column_stack([solve(rhs[:, c]) for c in range(3)])
    bb = b.reshape(k, m, 3)
    sigma = frame_noise(np.asarray(frames, np.float64)) if noise is None else float(noise)
    if sigma > 0:  # where a blendshape hardly moves a marker, its frames there carry only noise
        trust = np.minimum(1.0, np.linalg.norm(g, axis=2) / (evidence * sigma))
        bb = g + trust[:, :, None] * (bb - g)
        b = bb.reshape(k * m, 3)
    e_match = float(np.sum(psi[:, :, None] * (bb - target) ** 2))
    e_mesh = float(sum(np.sum((lap @ (bb[i] - g[i])) ** 2) for i in range(k)) / m)
    e_ceg = float(np.sum((ceg_g @ (b - sv).reshape(k, m * 3)) ** 2) / m)
    energies = {"match": e_match, "mesh": alpha * e_mesh, "ceg": beta * e_ceg,
                "total": e_match + alpha * e_mesh + beta * e_ceg}
    return AlignResult(bb, g, keys, rho, energies)


def frame_noise(frames: np.ndarray) -> float:
    """A robust estimate of the marker noise (σ per coordinate) of a sequence of frames (F, M, 3):
    the median absolute second difference over frames, markers and coordinates, ``1.4826 MAD / √6``
    (most markers rest in most frames, so the median sees noise; the neutral's own noise cancels)."""
    a = np.asarray(frames, np.float64)
    if len(a) < 3:
        return 0.0
    d2 = a[2:] - 2 * a[1:-1] + a[:-2]
    return float(1.4826 * np.median(np.abs(d2)) / np.sqrt(6.0))


def _apex_targets(frames: np.ndarray, guesses: np.ndarray, purity: float,
                  apex: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each blendshape's target from the frames that show it at its apex (module notes, 4).

    Returns the frames used, the (K, F') weight of each in each target, the targets (K, M, 3) and
    which blendshapes some frame shows (K,)."""
    from stimulus_engine.characters.blendshape_weights import retarget_frames

    k = len(guesses)
    w = retarget_frames(frames, guesses, None, mu=0.0)  # (F, K): each frame explained by the guesses
    motion = w ** 2 * np.sum(np.asarray(guesses).reshape(k, -1) ** 2, axis=1)[None]
    share = motion / np.maximum(motion.sum(axis=1, keepdims=True), 1e-300)
    shows = share >= purity
    top = np.where(shows, w, 0.0).max(axis=0)
    chosen = shows & (w >= apex * top[None]) & (top[None] > 0)  # (F, K)
    keys = np.flatnonzero(chosen.any(axis=1))
    sel = chosen[keys].T.astype(np.float64)  # (K, F')
    sel /= np.maximum(sel.sum(axis=1, keepdims=True), 1.0)
    fitted = np.einsum("fk,kmc->fkmc", w[keys], guesses)  # each blendshape's fitted motion in each frame
    others = fitted.sum(axis=1)[:, None] - fitted  # (F', K, M, 3): the rest of each frame
    target = np.einsum("kf,fkmc->kmc", sel, frames[keys][:, None] - others)
    shown = chosen.any(axis=0)
    target[~shown] = guesses[~shown]
    return keys, sel, target, shown


def densify(initial: np.ndarray, sparse: np.ndarray, markers: np.ndarray, neutral: np.ndarray) -> np.ndarray:
    """Dense blendshapes from sparse ones: each dense guess scaled vertex by vertex by a smooth gain.

    A marker's gain is how much longer the aligned sparse blendshape is than the dense guess there
    (``δb·δg / δg·δg``; at markers the guess hardly moves, the blendshape's overall gain); a
    thin-plate spline through the markers spreads the gains over the face. Scaling the guess
    rather than adding a vector correction keeps its local shape: where two surfaces meet (the
    corners of the mouth, the lid margins) neighbouring vertices move alike and no triangle folds.

    Parameters
    ----------
    initial : (K, N, 3) array
        The dense initial guesses (deformation transfer or RBF).
    sparse : (K, M, 3) array
        The aligned sparse blendshapes.
    markers : (M,) int array
        The marker vertices.
    neutral : (N, 3) array
        The target's neutral (the spline's points).
    """
    g = np.asarray(initial, np.float64)
    gm = g[:, markers]
    gg = np.einsum("kmc,kmc->km", gm, gm)
    bg = np.einsum("kmc,kmc->km", np.asarray(sparse, np.float64), gm)
    overall = bg.sum(axis=1, keepdims=True) / np.maximum(gg.sum(axis=1, keepdims=True), 1e-300)
    strong = gg > (_SUPPORT_FRACTION ** 2) * gg.max(axis=1, keepdims=True)
    gain = np.where(strong, bg / np.maximum(gg, 1e-300), overall)  # (K, M)
    neutral = np.asarray(neutral, np.float64)
    spline = RBFInterpolator(neutral[markers], gain.T, kernel="thin_plate_spline", degree=1, smoothing=GAIN_SMOOTHING)
    where = np.flatnonzero(np.abs(g).max(axis=(0, 2)) > 0)
    out = g.copy()
    out[:, where] *= spline(neutral[where]).T[:, :, None]
    return out


# --------------------------------------------------------------------------------------------
# Whole rigs
# --------------------------------------------------------------------------------------------


def face_length(rig: FaceRig, vertices: np.ndarray | None = None) -> float:
    """The face's length, forehead top to chin (the length a grid frames every face by)."""
    lm = rig.landmark_points(vertices)
    return float(np.linalg.norm(lm["forehead_top"] - lm["chin"]))


#: How much further a designed cartoon's expressions move than the rig's, in units of its face (``face_units:
#: larger``): stylised shapes read as more intense (thesis §6.5), and an animator exaggerates a cartoon's
#: expressions, where the range-of-motion alignment alone left a cartoon's mouth and brows 2-3 % short.
CARTOON_EXPRESSIVENESS = 1.1


def face_width(rig: FaceRig, vertices: np.ndarray | None = None) -> float:
    """The face's width, between its sides in front of the ears (``face_right`` to ``face_left``)."""
    lm = rig.landmark_points(vertices)
    return float(np.linalg.norm(lm["face_left"] - lm["face_right"]))


def range_of_motion(names: list[str], *, expressions: bool = False, steps: int = 1, hold: int = 0) -> np.ndarray:
    """A range-of-motion training sequence as blendshape weights, (F, K).

    Each blendshape of ``names`` alone rises in ``steps`` steps to 1, holds ``hold`` frames and
    falls back (default: neutral, apex, neutral — a FACS calibration in which each action is
    shown alone); then (``expressions``) each FACS recipe expression the names can show (all
    of its shapes among ``names``) the same way.
    """
    from stimulus_engine.characters.expressions import EXPRESSIONS, expression_weights, facs_recipes

    idx = {n: i for i, n in enumerate(names)}
    targets = [np.eye(len(names))[i] for i in range(len(names))]
    if expressions:
        for e in [*EXPRESSIONS, *sorted(set(facs_recipes()["expressions"]) - set(EXPRESSIONS))]:
            w = expression_weights(e)
            if w and all(s in idx for s in w):
                v = np.zeros(len(names))
                for s, x in w.items():
                    v[idx[s]] = x
                targets.append(v)
    ramp = np.concatenate([np.arange(1, steps + 1) / steps, np.ones(hold), np.arange(steps - 1, -1, -1) / steps])
    return np.concatenate([np.zeros((1, len(names)))] + [ramp[:, None] * t[None] for t in targets])


def transfer_blendshapes(rig: FaceRig, target: np.ndarray, method: str = "aligned", *,
                         names: list[str] | None = None, frames: np.ndarray | None = None,
                         markers: np.ndarray | None = None, n_markers: int = 120,
                         alpha: float = ALIGN_ALPHA, beta: float = ALIGN_BETA,
                         dense_base: str = "deformation_transfer", face_units: str = "length",
                         reference: tuple[np.ndarray, dict[str, np.ndarray]] | None = None) -> dict[str, np.ndarray]:
    """``rig``'s blendshapes carried onto the neutral ``target`` (same topology) as dense deltas.

    Parameters
    ----------
    rig : FaceRig
        The source rig (its neutral and blendshapes).
    target : (N, 3) array
        The target's neutral, in the rig's topology.
    method : {"aligned", "rbf", "deformation_transfer"}
    names : list of str, optional
        The blendshapes to transfer (default: all of the rig's, sorted).
    frames : (F, M, 3) array, optional
        ``aligned``: the target's training sequence at ``markers`` as displacements from its
        neutral. Default: the rig's :func:`range_of_motion` scaled by the ratio of the faces'
        sizes (target / rig; see ``face_units``).
    markers : (M,) int array, optional
        Marker vertices (default :func:`~stimulus_engine.characters.markers.marker_vertices`).
    n_markers : int
        Number of markers when they are chosen here.
    alpha, beta : float
        E_Align's weights (``aligned``).
    dense_base : {"deformation_transfer", "rbf"}
        ``aligned``: the dense blendshapes the markers' gains scale (default deformation
        transfer: on one topology it keeps each triangle's deformation; ``rbf`` needs no
        triangles to agree).
    face_units : {"length", "larger"}
        ``aligned``: the size the default training sequence is scaled by: the face's length
        (forehead to chin), or the larger of its length's and its width's ratios, each
        blendshape then scaled up where its landmarks fall short of :data:`CARTOON_EXPRESSIVENESS`
        times the rig's motion in those units (a designed cartoon, whose face is wider than long, then moves
        at least as far in units of either).
    reference : (neutral, blendshapes), optional
        With ``face_units: larger``: the shape whose motion the transferred blendshapes must reach
        (default the rig's own), e.g. the character's realistic level, its blendshapes by name.

    Returns
    -------
    dict of str to (N, 3) array
        Delta blendshapes of the target, by name.
    """
    from stimulus_engine.characters.expressions import deformation_transfer

    if method not in TRANSFER_METHODS:
        raise ValueError(f"unknown transfer method '{method}' (expected one of: {', '.join(TRANSFER_METHODS)})")
    names = sorted(rig.blendshapes) if names is None else list(names)
    target = np.asarray(target, np.float64)
    deltas = np.stack([rig.blendshapes[n] for n in names])
    def transferred() -> np.ndarray:  # each blendshape by deformation transfer
        return np.stack([deformation_transfer(rig.vertices, rig.vertices + d, target, rig.faces) - target
                         for d in deltas])

    if method == "deformation_transfer":
        return dict(zip(names, transferred()))
    markers = marker_vertices(rig, n_markers) if markers is None else np.asarray(markers)
    warp = rbf_warp(rig.vertices[markers], target[markers])
    if method == "rbf" or dense_base == "rbf":
        dense_g = warp_deltas(warp, rig.vertices, deltas)
        if method == "rbf":
            return dict(zip(names, dense_g))
    else:
        dense_g = transferred()
    s = deltas[:, markers]
    clean = frames is None  # the rig's own range of motion: no noise to bound against
    if frames is None:
        ratio = face_length(rig, target) / face_length(rig)
        if face_units == "larger":
            ratio = max(ratio, face_width(rig, target) / face_width(rig))
        frames = ratio * np.einsum("fk,kmc->fmc", range_of_motion(names), s)
    guess = warp_deltas(warp, rig.vertices[markers], s)  # the thesis's RBF guesses at the markers
    res = align_blendshapes(s, frames, guess, target[markers], alpha=alpha, beta=beta, noise=0.0 if clean else None,
                            matching="similarity" if clean else ALIGN_MATCHING)  # each clean frame is one blendshape
    dense = densify(dense_g, res.blendshapes, markers, target)
    if face_units == "larger":
        ref_v, ref = (rig.vertices, deltas) if reference is None else (
            np.asarray(reference[0], np.float64), np.stack([reference[1][n] for n in names]))
        dense = _at_least_as_far(rig, ref_v, ref, target, dense)
    return dict(zip(names, dense))


def _at_least_as_far(rig: FaceRig, ref_v: np.ndarray, ref: np.ndarray, target: np.ndarray,
                     dense: np.ndarray) -> np.ndarray:
    """Each transferred blendshape scaled up, where it falls short, to move each face landmark it moves
    most (a mouth corner, a brow, a lid: those moving at least half as far as its most-moving one) at least
    :data:`CARTOON_EXPRESSIVENESS` times as far in units of its face's length and of its width as the
    reference (the rig's own, or a character's realistic level, with neutral ``ref_v``) does in its face's."""
    sets = [np.asarray(v) for k, v in sorted(rig.landmarks.items()) if k not in ("eye_right", "eye_left")
            and not k.startswith("pupil_")]

    def moved(d: np.ndarray) -> np.ndarray:  # (shapes, landmarks)
        return np.stack([np.linalg.norm(d[:, idx].mean(axis=1), axis=1) for idx in sets], axis=1)

    src, got = moved(ref), moved(dense)
    units = max(face_length(rig, target) / face_length(rig, ref_v), face_width(rig, target) / face_width(rig, ref_v))
    main = src >= 0.5 * src.max(axis=1, keepdims=True)
    ratio = np.where(main & (got > 0), CARTOON_EXPRESSIVENESS * units * src / np.maximum(got, 1e-300), 0.0)
    gain = np.where(src.max(axis=1) > 0, ratio.max(axis=1), 1.0)
    return dense * np.maximum(gain, 1.0)[:, None, None]
