"""The realistic template head (fsaverage BEM, 5 mm grid) and anatomical labels end to end:
generators planted at known MNI positions come back, through the inverse and the atlas, with
their regions. A right fusiform generator (deep, ventral), which the minimum-norm estimates put
20-40 mm off (sLORETA: in the cerebellum), comes back in the right fusiform gyrus with the LCMV
beamformer (``method: LCMV``)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.erp.atlas import atlas_available

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not atlas_available(), reason="needs the atlases: pip install 'appeal-lab[atlas]'")]

PLANTED = {"Occipital_Inf_R": (44.0, -76.0, -8.0), "Occipital_Mid_L": (-30.0, -85.0, 10.0), "Precuneus": (0.0, -60.0, 45.0)}


@pytest.fixture(scope="module")
def head():
    import mne

    from analysis.erp.channels import make_montage
    from analysis.erp.source import add_forward, template_head

    montage = make_montage("biosemi128")
    info = mne.create_info(montage.ch_names, 256.0, "eeg")
    info.set_montage(montage)
    return add_forward(template_head(info, 5.0, bem="fsaverage"), info), info


def test_fsaverage_surfaces_are_nested_and_the_grid_is_in_mni_space():
    from analysis.erp.fsaverage_head import fsaverage_surfaces

    s = fsaverage_surfaces()
    c = s["inner_skull"][0].mean(axis=0)
    r = {k: np.linalg.norm(v[0] - c, axis=1) for k, v in s.items()}
    assert (r["outer_skull"] > r["inner_skull"]).all() and (r["outer_skin"] > r["outer_skull"]).all()
    gap = (r["outer_skin"] - r["inner_skull"]) * 1e3
    assert 6 - 1e-6 <= gap.min() and gap.max() <= 16 + 1e-6


def _planted(hm, info, pos):
    """60 epochs of a 50 nAm generator at ``pos`` (the orientation the scalp sees best), noisy."""
    import mne

    mni, gain = hm.mni, hm.forward["sol"]["data"]
    v = int(np.argmin(np.linalg.norm(mni - np.asarray(pos), axis=1)))
    g = gain[:, 3 * v:3 * v + 3]
    ori = np.linalg.svd(g - g.mean(axis=0), full_matrices=False)[2][0]
    topo = g @ ori * 50e-9
    times = np.arange(-0.2, 0.3, 1 / 256)
    wave = np.exp(-0.5 * ((times - 0.17) / 0.015) ** 2)
    data = topo[None, :, None] * wave[None, None, :] + np.random.default_rng(0).normal(
        0, np.abs(topo).max(), (60, len(topo), len(times)))
    events = np.c_[np.arange(60) * 300, np.zeros(60, int), np.ones(60, int)]
    return v, mne.EpochsArray(data, info, tmin=times[0], events=events, event_id={"face": 1}, verbose="error")


def test_a_right_fusiform_generator_comes_back_with_the_beamformer(head):
    from analysis.erp.atlas import label_peaks
    from analysis.erp.source import subject_source_maps

    hm, info = head
    v, epochs = _planted(hm, info, (40.0, -55.0, -15.0))
    assert label_peaks(hm.mni[v][None])["region"].iloc[0] == "Fusiform_R"
    peak = {}
    for method in ("LCMV", "sLORETA"):
        maps = subject_source_maps(epochs, hm, {"face": ["face"]}, {"N170": (0.15, 0.19)}, method)
        peak[method] = hm.mni[int(np.argmax(maps[("N170", "face")]))]
    # measured: LCMV 7 mm off in the right fusiform gyrus; sLORETA 35 mm off, in the cerebellum
    assert np.linalg.norm(peak["LCMV"] - hm.mni[v]) <= 15.0
    assert label_peaks(peak["LCMV"][None])["region"].iloc[0] == "Fusiform_R"
    assert np.linalg.norm(peak["sLORETA"] - hm.mni[v]) > np.linalg.norm(peak["LCMV"] - hm.mni[v])


def test_planted_generators_come_back_with_their_regions(head):
    from analysis.erp.atlas import label_peaks
    from analysis.erp.source import subject_source_maps

    hm, info = head
    mni = hm.mni
    assert len(mni) > 10_000 and mni[:, 0].min() < -60 and mni[:, 1].min() < -95  # a whole brain at 5 mm
    for region, pos in PLANTED.items():
        v, epochs = _planted(hm, info, pos)
        assert label_peaks(mni[v][None])["region"].iloc[0].startswith(region)  # the planted voxel itself
        maps = subject_source_maps(epochs, hm, {"face": ["face"]}, {"N170": (0.15, 0.19)})
        peak = mni[int(np.argmax(maps[("N170", "face")]))]
        # measured (sLORETA): 21, 12 and 7 mm off, each in its planted region
        assert np.linalg.norm(peak - mni[v]) <= 25.0, (region, peak)
        assert label_peaks(peak[None])["region"].iloc[0].startswith(region), (region, peak)
