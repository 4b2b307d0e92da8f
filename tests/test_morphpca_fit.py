"""Loadings fitted as images (``MorphModel.project(fit="image")``) and a held-out fraction spread
over the set (``--holdout-every``): faces of people not in a London face space."""

from __future__ import annotations

import numpy as np
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.morphpca import build_model, psnr
from stimulus_engine.morphpca.workflow import read_morph_inputs


@pytest.fixture(scope="module")
def london_space(shared_data):
    """The first 15 London identities of the group, every fifth held out, registered to 120x100 with .tem."""
    from stimulus_engine.morphpca.io import list_images

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("APPEAL_DATA", str(shared_data))
        files = list_images(["data:london-frl-all/neutral_front/*_03.jpg"])[:15]
    inputs = read_morph_inputs(files, keypoints="tem", register=True, size="120x100", holdout_every=5)
    n = inputs.n_train
    model = build_model(inputs.images[:n], landmarks=inputs.landmarks[:n])
    return files, inputs, model


def test_holdout_every_moves_every_kth_image_to_the_end(london_space):
    files, inputs, _ = london_space
    assert inputs.n_train == 12 and inputs.files[12:] == files[4::5]
    assert inputs.files[:12] == [f for i, f in enumerate(files) if i % 5 != 4]
    with pytest.raises(AppealInputError, match="--holdout-every: give either"):
        read_morph_inputs(files, holdout=2, holdout_every=5)


def test_a_vector_in_the_span_gets_its_own_loadings_back(london_space):
    model = london_space[2]
    lo = model.loadings[:3]
    np.testing.assert_allclose(model.project(model.vectors(lo), fit="image"), lo, atol=0.02 * np.abs(lo).max())
    with pytest.raises(AppealInputError, match="fit: expected 'orthogonal' or 'image'"):
        model.project(model.vectors(lo), fit="nearest")


def test_image_fit_reconstructs_held_out_people_better_than_the_orthogonal_projection(london_space):
    _, inputs, model = london_space
    held, pts = np.stack(inputs.images[12:]), inputs.landmarks[12:]
    enc = model.encode(held, pts)
    score = lambda lo: np.mean([psnr(a, b) for a, b in zip(held, model.reconstruct(lo))])  # noqa: E731
    orth, image = score(model.project(enc)), score(model.project(enc, fit="image"))
    assert image > orth + 0.5, (image, orth)
