"""Stimulus engine: 3D face correspondence, texture transfer, morphing, rendered grids, and
2D morph-space PCA face models."""
