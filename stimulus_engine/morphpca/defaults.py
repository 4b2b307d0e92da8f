"""Defaults shared by the morph-PCA functions and the command line (no heavy imports here)."""

#: Weight of texture against warp when fitting a target's loadings (:func:`~.project.target_loadings`).
#: Measured SSIM of projected expressions to the target's true image: synthetic faces (12
#: expressions, benchmarks/morphpca.py) 0.9500 / 0.9692 / 0.9715 / 0.9686 at 1 / 0.1 / 0.03 /
#: 0.01; a smile between London-set people (30 ordered pairs of 6 people, each person's
#: model from a neutral→smile morph, compared with the target's own smiling photo) 0.845 at 0.1,
#: 0.870 at 0.03 (naive loading transfer 0.812, the target's neutral photo 0.640). 0.1 stays
#: the default: at 0.03 the mimicry measures separate a faithful from a reversed synthetic
#: mimic less well (correlation of the first 3 components 0.35 instead of above 0.4,
#: tests/test_morphpca_mimicry.py); pass 0.03 (``--texture-weight 0.03``) for single smiles.
DEFAULT_TEXTURE_WEIGHT = 0.1
