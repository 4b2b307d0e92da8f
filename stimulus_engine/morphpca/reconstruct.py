"""Reconstruction: loadings → morph vector → image (Nagle et al. §2, steps 1–3).

The texture is displaced by the warp field with *backward* mapping: the warp (mean shape →
image) is inverted by fixed-point iteration and the texture is sampled at the inverse
positions, so every output pixel gets a value (no holes). Before inversion, regions where the
warp would fold over (Jacobian determinant ≤ 0, e.g. after strong caricaturing or extreme
loadings) are smoothed until the warp is one-to-one (no fold-over artefacts).

Speed: warp fields are smooth (the DIS flows are searched at half resolution and blurred), so
the fold check and the inversion run on the displacement at half resolution (images of at least
:data:`HALF_RESOLUTION_MIN` pixels each way); the inverse is upsampled bilinearly and the texture
is sampled at full resolution. :class:`Reconstructor` keeps the model's components in that
pixel order (texture ``(h, w, 3)``, then the half-resolution displacement), so a batch is one
float32 matrix product into a reused buffer, followed per face by OpenCV remaps into
preallocated work arrays.
"""

from __future__ import annotations

import threading

import cv2
import numpy as np

from stimulus_engine.morphpca.flow import fix_foldovers, grid, invert_displacement
from stimulus_engine.morphpca.morphvec import TEXTURE_SCALE
from stimulus_engine.geometry.sampling import sample_bilinear

__all__ = ["HALF_RESOLUTION_MIN", "render_morph", "render_vectors", "Reconstructor", "reconstruct_image"]

#: Images at least this many pixels high and wide invert their warp at half resolution.
HALF_RESOLUTION_MIN = 32

#: Upper bound of :class:`Reconstructor`'s product buffer; larger batches are split into equal
#: chunks (one product for 200 faces of 240×200 is ~25 % faster than 128 + 72).
MAX_BUFFER_BYTES = 192 * 2**20


class _Renderer:
    """Grids and work buffers for rendering faces of one size (nothing allocated per face)."""

    def __init__(self, size: tuple[int, int], iterations: int = 6, fix: bool = True):
        h, w = self.size = (int(size[0]), int(size[1]))
        self.halve = min(h, w) >= HALF_RESOLUTION_MIN
        self.low = ((h + 1) // 2, (w + 1) // 2) if self.halve else (h, w)
        hl, wl = self.low
        # low-resolution pixel units → full-resolution pixel units (x, y)
        self.scale = np.array([w / wl, h / hl], np.float32)
        self.iterations, self.fix = iterations, fix
        self.grid, self.grid_low = grid(h, w), grid(hl, wl)
        self.work = tuple(np.empty((hl, wl, 2), np.float32) for _ in range(3))  # -d, e, positions
        self.uniform = bool(self.scale[0] == self.scale[1])
        self.e_full = np.empty((h, w, 2), np.float32)
        self.pos = np.empty((h, w, 2), np.float32)
        self.image = np.empty((h, w, 3), np.float32)

    @property
    def n_texture(self) -> int:
        return self.size[0] * self.size[1] * 3

    def low_displacement(self, d: np.ndarray) -> np.ndarray:
        """A full-resolution displacement ``(h, w, 2)`` at the inversion resolution, in its pixel units."""
        d = np.ascontiguousarray(d, np.float32)
        if not self.halve:
            return d
        low = cv2.resize(d, self.low[::-1], interpolation=cv2.INTER_AREA)
        low /= self.scale
        return low

    def render(self, texture: np.ndarray, d_low: np.ndarray) -> np.ndarray:
        """Sample ``texture`` (h, w, 3) at the inverse of the warp ``d_low`` into ``self.image`` (unclipped)."""
        if self.fix:
            d_low = fix_foldovers(d_low)  # returns the field itself when nothing folds
        e = invert_displacement(d_low, self.iterations, base=self.grid_low, buffers=self.work)
        if not self.halve:
            np.add(self.grid, e, out=self.pos)
        else:
            e = cv2.resize(e, self.size[::-1], dst=self.e_full, interpolation=cv2.INTER_LINEAR)
            if self.uniform:  # even sizes: scale 2 in x and y, one fused OpenCV pass
                cv2.scaleAdd(e, float(self.scale[0]), self.grid, dst=self.pos)
            else:
                e *= self.scale
                np.add(self.grid, e, out=self.pos)
        return sample_bilinear(texture, self.pos, out=self.image)

    def pixel_rows(self, vectors: np.ndarray, texture_scale: float, absolute: bool) -> np.ndarray:
        """Serialised morph vectors ``(n, D)`` → rows ``[texture (h, w, 3) · scale, low-res displacement]``.

        ``texture_scale`` multiplies the stored texture values (0–255 scale): ``1 / TEXTURE_SCALE`` gives [0, 1].

        ``absolute``: the warp part holds positions (a mean or a whole vector), so the pixel grid
        is subtracted; relative vectors (components) are displacements already.
        """
        h, w = self.size
        planes = np.atleast_2d(np.asarray(vectors, np.float32)).reshape(-1, 5, w, h)  # serialised: (c, x, y)
        n, nt = planes.shape[0], self.n_texture
        hl, wl = self.low
        rows = np.empty((n, nt + hl * wl * 2), np.float32)
        for i in range(n):
            # (3, w, h) → (h, w, 3) in one strided copy, scaled on the way
            np.multiply(planes[i, :3].T, np.float32(texture_scale), out=rows[i, :nt].reshape(h, w, 3))
            d = planes[i, 3:].T - self.grid if absolute else planes[i, 3:].T
            rows[i, nt:] = self.low_displacement(d).ravel()
        return rows

    def render_rows(self, rows: np.ndarray, out: np.ndarray, as_uint8: bool) -> None:
        """Render pixel-order rows into ``out`` ``(n, h, w, 3)`` (uint8 rows carry +0.5 for rounding)."""
        h, w = self.size
        nt = self.n_texture
        hl, wl = self.low
        for i, row in enumerate(rows):
            img = self.render(row[:nt].reshape(h, w, 3), row[nt:].reshape(hl, wl, 2))
            if as_uint8:
                np.clip(img, 0.0, 255.0, out=img)
                out[i] = img  # truncation of value + 0.5 = rounding
            else:
                np.clip(img, 0.0, 1.0, out=out[i])


_local = threading.local()


def _renderer(size: tuple[int, int], iterations: int = 6, fix: bool = True) -> _Renderer:
    """A cached renderer per thread, size and settings (its buffers are reused between calls)."""
    cache = _local.__dict__.setdefault("renderers", {})
    key = (int(size[0]), int(size[1]), iterations, fix)
    if key not in cache:
        cache[key] = _Renderer(size, iterations, fix)
    return cache[key]


def render_morph(texture: np.ndarray, warp: np.ndarray, *, fix: bool = True, iterations: int = 6) -> np.ndarray:
    """Image from a texture on the mean shape and its absolute warp field.

    Parameters
    ----------
    texture : (h, w, 3) float32 in [0, 1]
    warp : (h, w, 2) float32
        Absolute positions in the output image of every mean-shape pixel.
    fix : bool
        Repair fold-overs first (see :func:`stimulus_engine.morphpca.flow.fix_foldovers`).
    iterations : int
        Fixed-point iterations of the warp inversion.

    Returns
    -------
    (h, w, 3) float32 in [0, 1]
    """
    r = _renderer(warp.shape[:2], iterations, fix)
    d_low = r.low_displacement(np.asarray(warp, np.float32) - r.grid)
    img = r.render(np.ascontiguousarray(texture, np.float32), d_low)
    return np.clip(img, 0.0, 1.0)


def render_vectors(vectors: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Images ``(n, h, w, 3)`` float32 in [0, 1] from absolute morph vectors ``(n, D)``."""
    r = _renderer(size)
    rows = r.pixel_rows(vectors, 1.0 / TEXTURE_SCALE, absolute=True)
    out = np.empty((rows.shape[0], *r.size, 3), np.float32)
    r.render_rows(rows, out, as_uint8=False)
    return out


class Reconstructor:
    """Fast repeated reconstruction from one model: the function a trial loop calls.

    At construction the model's components and mean are reordered once into pixel order
    (texture ``(h, w, 3)`` then the half-resolution displacement; the pixel grid, the texture
    scale and the uint8 rounding offset folded into the mean). A call is then one float32
    matrix product for the whole batch (into a reused buffer of at most
    :data:`MAX_BUFFER_BYTES`), and per face the fold-over check, the warp inversion and one remap
    into preallocated arrays.

    A single face costs one matrix–vector product over the whole component matrix, which is
    bound by memory bandwidth; ask for many faces in one call where possible (e.g. all frames
    of a trial before it starts).

    Examples
    --------
    >>> rec = Reconstructor(model)                      # doctest: +SKIP
    >>> frame = rec(np.zeros(model.n_components))       # the mean face, uint8 RGB
    >>> frames = rec(loadings)                          # (n, k) → (n, h, w, 3) uint8
    """

    def __init__(self, model, *, as_uint8: bool = True, iterations: int = 6):
        self.size = tuple(model.size)
        self.as_uint8 = as_uint8
        self._renderer = _Renderer(self.size, iterations)  # own buffers: safe next to other renderers
        scale = 1.0 if as_uint8 else 1.0 / TEXTURE_SCALE  # uint8: texture stays on the 0–255 scale
        self.k = int(model.components.shape[0])
        # rows 0..k-1: components; row k: the mean (grid subtracted, +0.5 for uint8 rounding),
        # so that [loadings, 1] @ matrix is the whole reconstruction in one product
        self.matrix = np.empty((self.k + 1, self._renderer.n_texture + 2 * np.prod(self._renderer.low)), np.float32)
        self.matrix[: self.k] = self._renderer.pixel_rows(model.components, scale, absolute=False)
        self.matrix[self.k] = self._renderer.pixel_rows(model.mean, scale, absolute=True)[0]
        if as_uint8:
            self.matrix[self.k, : self._renderer.n_texture] += 0.5  # interpolation keeps +0.5: truncation rounds
        self._buffer = np.empty((0, self.matrix.shape[1]), np.float32)

    def _rows(self, lo: np.ndarray) -> np.ndarray:
        """Pixel-order rows of a chunk of loadings ``(m, ≤ k)``: one float32 product into a reused buffer."""
        m = lo.shape[0]
        if self._buffer.shape[0] < m:
            self._buffer = np.empty((m, self.matrix.shape[1]), np.float32)
        ext = np.zeros((m, self.k + 1), np.float32)
        ext[:, : lo.shape[1]] = lo
        ext[:, self.k] = 1.0
        return np.matmul(ext, self.matrix, out=self._buffer[:m])

    def __call__(self, loadings: np.ndarray) -> np.ndarray:
        single = np.asarray(loadings).ndim == 1
        lo = np.atleast_2d(np.asarray(loadings, np.float32))
        if lo.shape[1] > self.k:
            raise ValueError(f"loadings: expected at most {self.k} values per face (got {lo.shape[1]})")
        n = lo.shape[0]
        out = np.empty((n, *self.size, 3), np.uint8 if self.as_uint8 else np.float32)
        max_rows = max(1, MAX_BUFFER_BYTES // (4 * self.matrix.shape[1]))
        step = max(1, -(-n // max(1, -(-n // max_rows))))  # equal chunks of at most max_rows
        for start in range(0, n, step):
            chunk = lo[start : start + step]
            self._renderer.render_rows(self._rows(chunk), out[start : start + len(chunk)], self.as_uint8)
        return out[0] if single else out


def reconstruct_image(model, loadings: np.ndarray) -> np.ndarray:
    """One image ``(h, w, 3)`` float32 in [0, 1] from ``loadings`` of ``model``.

    For many calls (inside a trial loop) keep a :class:`Reconstructor` instead.
    """
    return Reconstructor(model, as_uint8=False)(np.asarray(loadings, np.float32).ravel())
