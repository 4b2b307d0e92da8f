"""The overhang repair of :func:`stimulus_engine.correspondence.untangle.untangle`: folds where
the source reaches beyond the target's border (a rig's forehead beyond a face mask) are
re-placed off the target without moving a fitted vertex; folds on the target keep the
on-surface repair."""

from __future__ import annotations

import numpy as np

from stimulus_engine.correspondence.metrics import degenerate_triangles, flipped_triangles
from stimulus_engine.correspondence.untangle import untangle

N = 13  # a 13 x 13 grid on the unit square: columns at x = k/12
MASK = (0.25, 0.75)  # the target: the square [0.25, 0.75]^2 in z = 0 (a "mask" with a border)


def _plane(n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """An n x n vertex grid on [0, 1]^2 (z = 0), two triangles per cell, row-major vertices."""
    ij = np.indices((n - 1, n - 1)).reshape(2, -1).T
    a = ij[:, 0] * n + ij[:, 1]
    faces = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    y, x = np.divmod(np.arange(n * n), n)
    return np.column_stack([x / (n - 1), y / (n - 1), np.zeros(n * n)]), faces


def _onto_mask(p: np.ndarray) -> np.ndarray:
    """Closest points on the target square (clamped into it, z = 0)."""
    q = np.clip(p, MASK[0], MASK[1])
    q[:, 2] = 0.0
    return q


def _inside_mask(v: np.ndarray) -> np.ndarray:
    return ((v[:, :2] >= MASK[0] - 1e-9) & (v[:, :2] <= MASK[1] + 1e-9)).all(axis=1)


def _bad(v: np.ndarray, f: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return flipped_triangles(v, f, ref) | degenerate_triangles(v, f, ref)


FOLD = 6 * N + 1  # row 6, column 1 (x = 1/12): in the overhang left of the mask


def test_overhang_fold_is_repaired_without_moving_the_fit():
    ref, f = _plane()
    fitted = _inside_mask(ref)
    # the registration: the fitted part in place, the overhang left of the mask squeezed
    # towards it and curling away from the target (z), one vertex pushed across its neighbours
    reg = ref.copy()
    left = ref[:, 0] < MASK[0] - 1e-9
    reg[left, 0] = MASK[0] - 0.5 * (MASK[0] - ref[left, 0])
    reg[left, 2] = MASK[0] - ref[left, 0]
    reg[FOLD, [0, 2]] = [0.23, 0.04]  # where x = 0.21 of the source went: past column 2 (x = 1/6)
    assert flipped_triangles(reg, f, ref).sum() > 0
    res = untangle(reg, f, ref, _onto_mask, fitted=fitted, overhang_distance=0.05)
    assert res.folds_before > 0 and res.folds_after == 0 and not _bad(res.vertices, f, ref).any()
    # nothing fitted moved, only overhang vertices, and they stay off the target
    np.testing.assert_array_equal(res.vertices[fitted], reg[fitted])
    assert res.moved[FOLD] and not (res.moved & fitted).any()
    np.testing.assert_array_equal(np.flatnonzero(res.moved), res.off_surface)
    # the on-surface repair alone (no fitted mask) pulls the fit along: what the overhang
    # repair is for (the MediaPipe regression of issue 4)
    plain = untangle(reg, f, ref, _onto_mask)
    assert (plain.moved & fitted).any()
    assert np.abs(plain.vertices[fitted] - reg[fitted]).max() > 1e-3


def test_overhang_with_uniform_displacement_takes_the_source_shape():
    """The harmonic extension of a constant displacement is that constant: a folded overhang
    of a translated source gets exactly the translated source back."""
    ref, f = _plane()
    shift = np.array([0.02, -0.01, 0.0])
    reg = ref + shift
    reg[FOLD, 0] = 0.2 + shift[0]  # past column 2 (x = 1/6)
    fitted = _inside_mask(ref)
    res = untangle(reg, f, ref, lambda p: _onto_mask(p - shift) + shift, fitted=fitted, overhang_distance=0.05)
    assert res.folds_before > 0 and res.folds_after == 0
    np.testing.assert_allclose(res.vertices, ref + shift, atol=1e-6)
    np.testing.assert_array_equal(res.vertices[fitted], reg[fitted])


def test_unfitted_fold_on_the_target_keeps_the_on_surface_repair():
    """A fold whose vertices lie on the target (pruned matches on a surface that is there,
    like ICT's eyelid rims on james) is no overhang: the same repair as without a mask."""
    ref, f = _plane(9)
    folded = ref.copy()
    folded[40, :2] += [0.2, 0.17]  # the centre vertex pulled across its 1-ring
    flatten = lambda p: p * [1.0, 1.0, 0.0]  # noqa: E731
    none_fitted = untangle(folded, f, ref, flatten, fitted=np.zeros(len(ref), bool), overhang_distance=0.05)
    plain = untangle(folded, f, ref, flatten)
    assert plain.folds_before > 0 and plain.folds_after == 0
    np.testing.assert_array_equal(none_fitted.vertices, plain.vertices)
    np.testing.assert_array_equal(none_fitted.moved, plain.moved)
