"""Source-space summaries: template head, volume source space, inverse maps, voxel-wise contrasts.

Without user files the head is a three-shell sphere fitted to the montage
(:func:`mne.make_sphere_model`) with a volume source space inside it; a user's BEM,
``trans`` and ``subjects_dir`` (fsaverage's, say) replace it. Nothing is downloaded.

Coordinates are reported in MNI space. For the sphere template the montage's electrodes are
matched to the same 10-5 positions on MNE's fsaverage layout (by direction from each
sphere's centre) and an affine transform fitted between the two sets -- the "electrode
positions transformed to match the template head" of the thesis (§7.3). fsaverage's
surface RAS is MNI305 space.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError

__all__ = [
    "BASELINE",
    "level_activation",
    "HeadModel",
    "template_head",
    "add_forward",
    "head_to_mni_affine",
    "subject_source_maps",
    "contrast_clusters",
    "grid_adjacency",
    "map_peaks",
    "smooth_on_grid",
    "with_labels",
]


#: Key of the pre-stimulus window's maps among a subject's source maps.
BASELINE = "_baseline"


@dataclass
class HeadModel:
    """Conductor model, source space and transforms shared by all subjects.

    Attributes
    ----------
    bem : mne.bem.ConductorModel | str
        Sphere model or BEM solution file.
    src : mne.SourceSpaces
        Volume source space.
    trans : mne.transforms.Transform | str | None
        head <-> MRI transform (``None``: identity, sphere template).
    to_mni : ndarray, shape (4, 4)
        Affine from source-space coordinates (metres) to MNI (millimetres).
    kind : str
        ``"sphere"`` or ``"bem"``.
    forward : mne.Forward | None
        Forward solution of the montage's EEG channels (:func:`add_forward`), shared by the
        subjects whose electrodes sit at the same positions; ``None``: one per subject.
    """

    bem: object
    src: object
    trans: object
    to_mni: np.ndarray
    kind: str
    forward: object = None

    @property
    def positions(self) -> np.ndarray:
        """Used source positions (metres, source-space frame), shape (n_vox, 3)."""
        s = self.src[0]
        return s["rr"][s["vertno"]]

    @property
    def spacing(self) -> float:
        """The grid step (metres): the median distance to each voxel's nearest neighbour."""
        from scipy.spatial import cKDTree

        pos = self.positions
        return float(np.median(cKDTree(pos).query(pos, k=2)[0][:, 1]))

    @property
    def voxel_mm3(self) -> float:
        """One voxel's volume in mm³."""
        return (self.spacing * 1e3) ** 3

    @property
    def mni(self) -> np.ndarray:
        """Used source positions in MNI millimetres."""
        p = self.positions
        return p @ self.to_mni[:3, :3].T + self.to_mni[:3, 3]


def _fsaverage_trans():
    import mne

    return mne.read_trans(os.path.join(os.path.dirname(mne.__file__), "data", "fsaverage", "fsaverage-trans.fif"))


def _fit_center(xyz: np.ndarray) -> np.ndarray:
    """Least-squares sphere centre of points."""
    a = np.c_[2 * xyz, np.ones(len(xyz))]
    b = (xyz ** 2).sum(axis=1)
    sol = np.linalg.lstsq(a, b, rcond=None)[0]
    return sol[:3]


def head_to_mni_affine(info) -> np.ndarray:
    """Affine (4 x 4) from head coordinates (m) of ``info``'s electrodes to MNI (mm).

    Each EEG electrode is matched to the fsaverage 10-5 electrode with the nearest direction
    from the respective sphere centre; the affine is the least-squares fit between the
    matched positions.
    """
    import mne

    from analysis.erp.channels import make_montage

    picks = mne.pick_types(info, eeg=True, exclude=())
    ours = np.array([info["chs"][i]["loc"][:3] for i in picks])
    ours = ours[np.isfinite(ours).all(axis=1) & (np.abs(ours).sum(axis=1) > 0)]
    fs = make_montage("fsaverage_1005")
    native = mne.channels.compute_native_head_t(fs, verbose="error")
    head_mri = _fsaverage_trans()
    pos = fs.get_positions()["ch_pos"]
    theirs = np.array(list(pos.values()))
    theirs = mne.transforms.apply_trans(head_mri, mne.transforms.apply_trans(native, theirs))
    u1 = ours - _fit_center(ours)
    u2 = theirs - _fit_center(theirs)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    u2 /= np.linalg.norm(u2, axis=1, keepdims=True)
    match = np.argmax(u1 @ u2.T, axis=1)
    a = np.c_[ours, np.ones(len(ours))]
    coef = np.linalg.lstsq(a, theirs[match], rcond=None)[0]  # (4, 3)
    aff = np.eye(4)
    aff[:3, :3] = coef[:3].T * 1e3
    aff[:3, 3] = coef[3] * 1e3
    return aff


def template_head(info, spacing_mm: float = 7.0, *, bem: str | Path | None = None, trans: str | Path | None = None,
                  subjects_dir: str | Path | None = None, subject: str = "fsaverage") -> HeadModel:
    """The head model: a sphere fitted to the montage (default) or the user's BEM.

    Parameters
    ----------
    info : mne.Info
        Measurement info with the electrode positions (montage set).
    spacing_mm : float
        Grid spacing of the volume source space.
    bem, trans : path-like | None
        A BEM solution (``-bem-sol.fif``) and the head<->MRI transform; both or neither.
        ``bem="fsaverage"``: the realistic three-layer template built from the fsaverage
        surfaces MNE ships (:mod:`analysis.erp.fsaverage_head`; cached after the first run).
    subjects_dir : path-like | None
        FreeSurfer subjects folder (with ``bem``: the volume source space fills the
        subject's inner skull).
    subject : str
        Subject name in ``subjects_dir``.

    Returns
    -------
    HeadModel
    """
    import mne

    if bem == "fsaverage":  # the realistic template (analysis.erp.fsaverage_head), in MNI305 metres
        from analysis.erp.fsaverage_head import fsaverage_bem, fsaverage_trans_path

        sol = mne.read_bem_solution(str(fsaverage_bem()), verbose="error")
        src = mne.setup_volume_source_space(None, pos=float(spacing_mm), bem=sol, verbose="error")
        tr = mne.read_trans(str(fsaverage_trans_path()))
        if tr["from"] != mne.io.constants.FIFF.FIFFV_COORD_HEAD:
            tr = mne.transforms.invert_transform(tr)
        to_mni = np.eye(4)
        to_mni[:3, :3] *= 1e3
        return HeadModel(bem=sol, src=src, trans=tr, to_mni=to_mni, kind="fsaverage BEM")
    if bem is None:
        sphere = mne.make_sphere_model("auto", "auto", info, verbose="error")
        src = mne.setup_volume_source_space(pos=float(spacing_mm), sphere=sphere, verbose="error")
        return HeadModel(bem=sphere, src=src, trans=None, to_mni=head_to_mni_affine(info), kind="sphere")
    try:
        bem_sol = mne.read_bem_solution(bem, verbose="error")
        src = mne.setup_volume_source_space(subject, pos=float(spacing_mm), bem=bem_sol, subjects_dir=subjects_dir,
                                            verbose="error")
        tr = mne.read_trans(trans)
    except Exception as exc:  # noqa: BLE001 - user files: report, do not crash
        raise AppealInputError(f"{bem}: source.bem: cannot build the head model ({type(exc).__name__}: {exc})".splitlines()[0]) from None
    if tr["from"] != mne.io.constants.FIFF.FIFFV_COORD_HEAD:
        tr = mne.transforms.invert_transform(tr)
    head_mri = tr  # head -> MRI; MRI of fsaverage is MNI305
    to_mni = np.eye(4)
    to_mni[:3, :3] *= 1e3
    return HeadModel(bem=bem_sol, src=src, trans=head_mri, to_mni=to_mni, kind="bem")


def add_forward(head: HeadModel, info) -> HeadModel:
    """Compute the forward solution of ``info``'s EEG channels once and keep it in ``head``.

    Subjects recorded with the same montage then pick their channels from it
    (:func:`mne.pick_channels_forward`) instead of computing the same forward again. If it
    cannot be computed here, ``head.forward`` stays ``None`` and each subject computes (and,
    failing, reports) its own.
    """
    import mne

    try:
        head.forward = mne.make_forward_solution(info, trans=head.trans, src=head.src, bem=head.bem, eeg=True,
                                                 meg=False, verbose="error")
    except Exception as exc:  # noqa: BLE001 - an optimisation only; subjects report the error themselves
        from appeal.logs import logger

        logger.debug("shared forward solution not computed: %s", exc)
        head.forward = None
    return head


def _forward(head: HeadModel, info):
    """The forward solution for ``info``: the shared one when every EEG electrode sits where it
    was computed (the same numbers as computing it again), else a new one."""
    import mne

    fwd = head.forward
    if fwd is not None and not info["bads"]:
        at = {c["ch_name"]: c["loc"][:3] for c in fwd["info"]["chs"]}
        eeg = [info["chs"][i] for i in mne.pick_types(info, eeg=True, exclude=())]
        if all(c["ch_name"] in at and np.array_equal(at[c["ch_name"]], c["loc"][:3]) for c in eeg):
            return mne.pick_channels_forward(fwd, [c["ch_name"] for c in eeg], ordered=True, verbose="error")
    return mne.make_forward_solution(info, trans=head.trans, src=head.src, bem=head.bem, eeg=True, meg=False,
                                     verbose="error")


def subject_source_maps(epochs, head: HeadModel, groups: dict, windows: dict, method: str = "sLORETA",
                        snr: float = 3.0) -> dict:
    """Window-averaged source maps of one subject.

    Parameters
    ----------
    epochs : mne.Epochs
        The subject's clean epochs (EEG).
    head : HeadModel
        Shared head model.
    groups : dict
        level -> list of epoch event names averaged into that level's evoked response.
    windows : dict
        component -> (start, end) seconds.
    method : str
        ``"dSPM"``, ``"sLORETA"``, ``"MNE"``, ``"eLORETA"`` (minimum-norm, free orientation, depth
        0.8) or ``"LCMV"`` (:func:`_lcmv_apply`: a unit-noise-gain beamformer, which finds deep
        ventral generators — a right fusiform one — the minimum-norm estimates put 20-40 mm off).
    snr : float
        Assumed SNR; ``lambda2 = 1 / snr**2``.

    Returns
    -------
    dict
        (component, level) -> ndarray (n_vox,) of the window-mean source magnitude.
    """
    import mne

    ep = epochs.copy().set_eeg_reference("average", projection=True, verbose="error")
    fwd = _forward(head, ep.info)
    cov = mne.compute_covariance(ep, tmax=0.0, method="empirical", verbose="error")
    if method == "LCMV":
        return _window_maps(ep, groups, windows, _lcmv_apply(ep, fwd, cov))
    inv = mne.minimum_norm.make_inverse_operator(ep.info, fwd, cov, loose=1.0, depth=0.8, verbose="error")
    return _window_maps(ep, groups, windows, lambda evoked: mne.minimum_norm.apply_inverse(
        evoked, inv, lambda2=1.0 / snr ** 2, method=method, verbose="error"))


def _window_maps(ep, groups: dict, windows: dict, to_stc) -> dict:
    """(component, level) -> each level's evoked response through ``to_stc``, its magnitude
    averaged over the component's window (whole samples, as ``mne.Evoked.crop``)."""
    out = {}
    for level, names in groups.items():
        names = [n for n in names if n in ep.event_id and len(ep[n])]
        if not names:
            continue
        evoked = ep[names].average()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            stc = to_stc(evoked)
        for comp, (a, b) in windows.items():
            mask = (stc.times >= a - 0.5 / evoked.info["sfreq"]) & (stc.times <= b + 0.5 / evoked.info["sfreq"])
            out[(comp, level)] = np.abs(stc.data[:, mask]).mean(axis=1).astype(np.float32)
    return out


def _lcmv_apply(ep, fwd, noise_cov):
    """An LCMV beamformer (MNE: unit-noise-gain weights, the max-power orientation per voxel, 5 %
    regularisation, rank reduced where interpolated channels leave the data rank-deficient), its
    data covariance from the post-stimulus part of all epochs and its noise covariance from the
    baseline, as an evoked -> source estimate function."""
    import mne

    data_cov = mne.compute_covariance(ep, tmin=0.0, method="empirical", verbose="error")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        filters = mne.beamformer.make_lcmv(ep.info, fwd, data_cov, reg=0.05, noise_cov=noise_cov, pick_ori="max-power",
                                           reduce_rank=True, weight_norm="unit-noise-gain", verbose="error")
    return lambda evoked: mne.beamformer.apply_lcmv(evoked, filters, verbose="error")


def map_peaks(values: np.ndarray, mni: np.ndarray, n_peaks: int = 3, min_distance_mm: float = 30.0) -> list[int]:
    """Indices of the largest values at least ``min_distance_mm`` apart (greedy, largest first)."""
    order = np.argsort(values)[::-1]
    peaks: list[int] = []
    for i in order:
        if all(np.linalg.norm(mni[i] - mni[j]) >= min_distance_mm for j in peaks):
            peaks.append(int(i))
            if len(peaks) == n_peaks:
                break
    return peaks


def grid_adjacency(positions: np.ndarray, spacing: float):
    """Face-neighbour (6-connected) adjacency of voxels on a regular grid, as a sparse matrix."""
    from scipy.sparse import coo_matrix
    from scipy.spatial import cKDTree

    pairs = cKDTree(positions).query_pairs(r=spacing * 1.01, output_type="ndarray")
    n = len(positions)
    i = np.r_[pairs[:, 0], pairs[:, 1]]
    j = np.r_[pairs[:, 1], pairs[:, 0]]
    return coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))


def smooth_on_grid(maps: np.ndarray, positions: np.ndarray, fwhm: float) -> np.ndarray:
    """Gaussian smoothing of voxel maps ``(..., n_vox)`` on their (irregularly bounded) grid:
    each voxel the normalised Gaussian-weighted mean of the voxels within 3 σ (σ = FWHM / 2.355),
    so a constant map stays constant up to the brain's edge. ``fwhm`` in the positions' units."""
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree

    if fwhm <= 0:
        return np.asarray(maps, float)
    sigma = fwhm / (2.0 * np.sqrt(2.0 * np.log(2.0)))
    pos = np.asarray(positions, float)
    pairs = cKDTree(pos).query_pairs(r=3 * sigma, output_type="ndarray")
    n = len(pos)
    i = np.r_[pairs[:, 0], pairs[:, 1], np.arange(n)]
    j = np.r_[pairs[:, 1], pairs[:, 0], np.arange(n)]
    w = np.exp(-np.sum((pos[i] - pos[j]) ** 2, axis=1) / (2 * sigma**2))
    k = csr_matrix((w, (i, j)), shape=(n, n))
    k = csr_matrix(k.multiply(1.0 / np.asarray(k.sum(axis=1)).ravel()[:, None]))
    return np.asarray(maps, float) @ k.T


def contrast_clusters(diff: np.ndarray, head: HeadModel, *, p_threshold: float = 0.005, min_voxels: int = 25,
                      n_permutations: int = 1000, seed: int = 0, min_volume_mm3: float | None = None,
                      smoothing_fwhm_mm: float = 0.0) -> tuple[np.ndarray, pd.DataFrame]:
    """Voxel-wise paired test of one directed contrast with cluster statistics.

    Parameters
    ----------
    diff : ndarray, shape (n_subjects, n_vox)
        Per-subject difference maps (level A - level B).
    head : HeadModel
        Gives voxel positions (MNI) and adjacency.
    p_threshold : float
        One-sided uncorrected voxel threshold (thesis: .005).
    min_voxels : int
        Smallest reported cluster (thesis: 25).
    min_volume_mm3 : float, optional
        Smallest reported cluster as a volume (replaces ``min_voxels``): the thesis's 25
        voxels of 2 mm are 200 mm³, 0.6 voxels of a 7 mm grid — so its threshold can be asked
        for on any grid.
    smoothing_fwhm_mm : float
        Gaussian smoothing of each subject's map first (:func:`smooth_on_grid`; SPM: 8 mm).
    n_permutations : int
        Sign flips for the FWE-corrected cluster p-values
        (:func:`mne.stats.permutation_cluster_1samp_test`, cluster mass).
    seed : int
        Seed of the permutations.

    Returns
    -------
    t : ndarray, shape (n_vox,)
        The t map.
    table : pandas.DataFrame
        One row per cluster of at least ``min_voxels`` voxels, largest peak first: ``n_voxels``,
        ``volume_mm3``, ``peak_t`` (largest t in the cluster) and its one-sided ``peak_p_uncorrected``,
        ``p_fwe``, ``peak_difference`` (largest mean difference in the cluster) and its
        position ``x_mm``, ``y_mm``, ``z_mm`` (MNI) and ``hemisphere``. The position is that
        of the largest effect rather than of the largest t: with few subjects the t map is
        flat wherever between-subject spread scales with the signal, and its maximum wanders
        off the generator, while the mean difference peaks on it.
    """
    import mne
    from scipy import stats

    n = diff.shape[0]
    if n < 3:
        raise AppealInputError(f"source: voxel-wise tests need at least 3 subjects (got {n})")
    thresh = float(stats.t.ppf(1 - p_threshold, n - 1))
    pos = head.positions
    spacing, voxel_mm3 = head.spacing, head.voxel_mm3
    if min_volume_mm3 is not None:
        min_voxels = max(1, int(np.ceil(min_volume_mm3 / voxel_mm3 - 1e-9)))
    diff = smooth_on_grid(diff, pos, smoothing_fwhm_mm / 1e3)
    adjacency = grid_adjacency(pos, spacing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_obs, clusters, p_fwe, _ = mne.stats.permutation_cluster_1samp_test(
            diff, threshold=thresh, tail=1, adjacency=adjacency, n_permutations=n_permutations, rng=seed,
            out_type="indices", verbose="error")
    mni = head.mni
    effect = diff.mean(axis=0)
    rows = []
    for k, cl in enumerate(clusters):
        vox = np.asarray(cl[0] if isinstance(cl, tuple) else cl)
        if len(vox) < min_voxels:
            continue
        peak_t = vox[np.argmax(t_obs[vox])]
        peak = vox[np.argmax(effect[vox])]
        x, y, z = mni[peak]
        rows.append(dict(n_voxels=len(vox), volume_mm3=round(len(vox) * voxel_mm3, 1), peak_t=float(t_obs[peak_t]),
                         peak_p_uncorrected=float(stats.t.sf(t_obs[peak_t], n - 1)), p_fwe=float(p_fwe[k]),
                         peak_difference=float(effect[peak]),
                         x_mm=round(float(x), 1), y_mm=round(float(y), 1), z_mm=round(float(z), 1),
                         hemisphere="L" if x < -5 else ("R" if x > 5 else "midline")))
    cols = ["n_voxels", "volume_mm3", "peak_t", "peak_p_uncorrected", "p_fwe", "peak_difference", "x_mm", "y_mm", "z_mm", "hemisphere"]
    table = pd.DataFrame(rows, columns=cols).sort_values("peak_t", ascending=False, ignore_index=True)
    return t_obs, with_labels(table)


def with_labels(table: pd.DataFrame) -> pd.DataFrame:
    """The peaks' anatomical labels (:mod:`analysis.erp.atlas`; empty without the atlases)."""
    from analysis.erp.atlas import atlas_available, label_peaks

    for c in ("area", "brodmann", "region"):
        table[c] = pd.Series(dtype=object)
    if len(table) and atlas_available():
        labels = label_peaks(table[["x_mm", "y_mm", "z_mm"]].to_numpy(float))
        for c in ("area", "brodmann", "region"):
            table[c] = labels[c].to_numpy()
    return table


def level_activation(window: np.ndarray, baseline: np.ndarray, *, n_permutations: int = 1000, seed: int = 0,
                     alpha: float = 0.05) -> tuple[np.ndarray, np.ndarray, float]:
    """One level's activation: the window's source magnitude above the pre-stimulus one, voxel by
    voxel over subjects, FWE-corrected by the maximum statistic (thesis Fig. 7.8, upper panel).

    Parameters
    ----------
    window, baseline : ndarray, shape (n_subjects, n_vox)
        Each subject's window-mean and baseline-mean magnitude maps.

    Returns
    -------
    t : ndarray (n_vox,)
        Paired t of window − baseline.
    p_fwe : ndarray (n_vox,)
        One-sided FWE-corrected p (sign-flip permutations of the maximum t,
        :func:`mne.stats.permutation_t_test`).
    threshold : float
        The smallest t with ``p_fwe < alpha`` (inf when no voxel is significant).
    """
    import mne

    diff = np.asarray(window, float) - np.asarray(baseline, float)
    if diff.shape[0] < 3:
        raise AppealInputError(f"source: per-level maps need at least 3 subjects (got {diff.shape[0]})")
    t, p, _ = mne.stats.permutation_t_test(diff, n_permutations=n_permutations, tail=1, rng=seed, verbose="error")
    sig = p < alpha
    return t, p, float(t[sig].min()) if sig.any() else float("inf")
