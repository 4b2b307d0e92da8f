"""A photograph as a character's material (issue 49): pure functions on arrays.

* :func:`project_photo` lays the photograph into the rig's UV layout through the fitted camera:
  every texel's surface point is projected into the photograph and sampled, where that point is
  seen (in front in a depth buffer of the face, turned toward the camera);
* :func:`mirror_fill` completes what one side does not show from the other (the ICT layout is
  mirror-symmetric, ``u' = 1 - u``), :func:`smooth_fill` the rest from the seen texels
  (pull-push: each hole gets the mean of the nearest seen texels at the coarsest level that
  reaches them);
* :func:`iris_colour` samples the iris between the lids for the rig's eyeballs;
* :func:`surround_image` is the head-and-shoulders layer: the photograph with the face drawn by
  the mesh filled in from around it, so a changed face (an expression, a stylised shape) never
  shows the photographed one behind it.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.characters.photo_fit import OrthoCamera

__all__ = [
    "depth_buffer",
    "iris_colour",
    "mirror_fill",
    "padded",
    "photo_shading",
    "project_photo",
    "sh_basis",
    "smooth_fill",
    "surround_corners",
    "surround_image",
    "wide_blur",
]


def _sample(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` (H, W, C) at pixel positions ``xy`` (n, 2)."""
    import cv2

    img = np.ascontiguousarray(image, np.float32)
    n, cols = len(xy), 4096  # OpenCV's maps are images under 32767 pixels a side
    m = np.zeros((-(-n // cols) * cols, 2), np.float32)
    m[:n] = xy
    m = m.reshape(-1, cols, 2)
    out = cv2.remap(img, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(-1, img.shape[2] if img.ndim == 3 else 1)[:n]


def depth_buffer(camera: OrthoCamera, vertices: np.ndarray, faces: np.ndarray, shape: tuple[int, int],
                 step: int = 2) -> np.ndarray:
    """The nearest surface depth under every ``step``-th pixel of an image of ``shape``
    (``-inf`` where no triangle is), for telling seen surface points from hidden ones."""
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    h, w = (shape[0] + step - 1) // step, (shape[1] + step - 1) // step
    xy = camera.project(vertices) / step
    uv = np.column_stack([xy[:, 0] / w, 1.0 - xy[:, 1] / h])
    rows, cols, fid, bary = rasterize_uv(uv, np.asarray(faces, np.int64), w, h)
    z = np.einsum("ij,ij->i", bary, camera.depth(vertices)[faces[fid]])
    buf = np.full((h, w), -np.inf)
    np.maximum.at(buf, (rows, cols), z)
    return buf


def project_photo(photo: np.ndarray, camera: OrthoCamera, points: np.ndarray, normals: np.ndarray,
                  valid: np.ndarray, zbuf: np.ndarray, *, step: int = 2, tolerance: float = 0.25,
                  facing_from: float = 0.15, facing_full: float = 0.55) -> tuple[np.ndarray, np.ndarray]:
    """The photograph laid into a UV layout.

    Parameters
    ----------
    photo : (H, W, 3) array
    camera : OrthoCamera
    points, normals : (S, S, 3) arrays
        Each texel's surface point and unit normal (the fitted neutral).
    valid : (S, S) bool array
        Texels on the surface.
    zbuf : array
        :func:`depth_buffer` of the same surface (every ``step``-th pixel).
    tolerance : float
        Depth (model units) a texel may lie behind the buffer and still count as seen.
    facing_from, facing_full : float
        Cosine between normal and view direction from which a texel is used, and from which
        fully (grazing texels are stretched in the photograph).

    Returns
    -------
    texture : (S, S, 3) float array
        The photograph's colours (0-255) where seen, 0 elsewhere.
    weight : (S, S) float array
        How well each texel is seen, 0-1.
    """
    S = valid.shape
    idx = np.flatnonzero(valid)
    p = points.reshape(-1, 3)[idx]
    xy = camera.project(p)
    h, w = photo.shape[:2]
    inside = (xy[:, 0] >= 0) & (xy[:, 0] <= w - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= h - 1)
    r = np.clip((xy[:, 1] / step).astype(int), 0, zbuf.shape[0] - 1)
    c = np.clip((xy[:, 0] / step).astype(int), 0, zbuf.shape[1] - 1)
    seen = camera.depth(p) >= zbuf[r, c] - tolerance
    cos = normals.reshape(-1, 3)[idx] @ camera.view_direction
    weight = np.zeros(S[0] * S[1])
    weight[idx] = np.clip((cos - facing_from) / (facing_full - facing_from), 0, 1) * (inside & seen)
    tex = np.zeros((S[0] * S[1], 3))
    tex[idx] = _sample(photo, xy)[:, :3]
    return tex.reshape(*S, 3), weight.reshape(S)


def sh_basis(normals: np.ndarray) -> np.ndarray:
    """The nine real spherical harmonics of order <= 2 at unit ``normals`` ``(n, 3)`` (constants
    left out: the fit below scales each column)."""
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    return np.column_stack([np.ones_like(x), x, y, z, x * y, x * z, y * z, x * x - y * y, 3 * z * z - 1])


def photo_shading(texture: np.ndarray, weight: np.ndarray, normals: np.ndarray, exclude: np.ndarray | None = None,
                  *, rounds: int = 3) -> np.ndarray:
    """The photograph's own shading at every texel, relative to its mean over the face.

    The skin's luminance where it is seen well is fitted by the nine spherical harmonics of its
    normal (a face's light is smooth: order 2 holds 98 % of a Lambertian surface's irradiance;
    Basri & Jacobs 2003; Ramamoorthi & Hanrahan 2001) with one albedo for all of it, iteratively
    leaving out the texels it fits worst (brows, lips, hair over the forehead, a shadow's core:
    ``exclude`` leaves out regions known beforehand). Dividing the texture by it leaves the
    albedo, which the renderer's lights shade again.
    """
    lum = texture.reshape(-1, 3) @ np.array([0.2126, 0.7152, 0.0722])
    n = normals.reshape(-1, 3)
    use = (weight.ravel() > 0.8) & (lum > 1.0)
    if exclude is not None:
        use &= ~exclude.ravel()
    Y = sh_basis(n)
    c = np.zeros(9)
    c[0] = 1.0
    for _ in range(rounds):
        A, b = Y[use], np.log(np.maximum(lum[use], 1.0))
        c_lin = np.linalg.lstsq(A, np.exp(b), rcond=None)[0]
        r = np.abs(A @ c_lin - np.exp(b)) / np.maximum(np.exp(b), 1.0)
        keep = r <= np.percentile(r, 80)
        idx = np.flatnonzero(use)
        use = np.zeros_like(use)
        use[idx[keep]] = True
        c = c_lin
    shade = Y @ c
    mean = float(np.average(shade[weight.ravel() > 0.8])) if (weight > 0.8).any() else 1.0
    return np.clip(shade / max(mean, 1e-6), 0.35, 2.0).reshape(weight.shape)


def mirror_fill(texture: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Complete each side of a mirror-symmetric layout (``u' = 1 - u``) from the other: a texel
    seen poorly takes the mirrored texel's colour in proportion to what it lacks."""
    mt, mw = texture[:, ::-1], weight[:, ::-1]
    other = (1.0 - weight) * mw
    total = weight + other
    out = np.where(total[..., None] > 0, (weight[..., None] * texture + other[..., None] * mt)
                   / np.maximum(total, 1e-9)[..., None], 0.0)
    return out, np.clip(total, 0, 1)


def smooth_fill(texture: np.ndarray, weight: np.ndarray, *, threshold: float = 0.05) -> np.ndarray:
    """Texels seen with weight below ``threshold`` filled from the seen ones (pull-push).

    The weighted image is halved level by level (colour sums and weights) until nothing is
    empty; going back up, each level's holes take the coarser level's colour, and texels seen
    a little blend toward it by what they lack."""
    import cv2

    levels = [(texture * weight[..., None], weight.copy())]
    while min(levels[-1][1].shape) > 2 and (levels[-1][1] <= 1e-6).any():
        c, w = levels[-1]
        h2, w2 = (c.shape[0] + 1) // 2, (c.shape[1] + 1) // 2
        levels.append((cv2.resize(c, (w2, h2), interpolation=cv2.INTER_AREA) * 4,
                       cv2.resize(w, (w2, h2), interpolation=cv2.INTER_AREA) * 4))
    c, w = levels[-1]
    colour = c / np.maximum(w, 1e-9)[..., None]
    if (w <= 1e-6).all():
        colour[:] = 0
    else:
        colour[w <= 1e-6] = (c.reshape(-1, 3).sum(axis=0) / w.sum())
    for c, w in reversed(levels[:-1]):
        up = cv2.resize(colour, (c.shape[1], c.shape[0]), interpolation=cv2.INTER_LINEAR)
        own = c / np.maximum(w, 1e-9)[..., None]
        a = np.clip(w, 0, 1)[..., None]
        colour = a * own + (1 - a) * up
    keep = (weight >= threshold)[..., None]
    return np.where(keep, np.where(weight[..., None] >= 1, texture, colour), colour)


def iris_colour(photo: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """The iris colour between one eye's six landmarks (iBUG order): the median of the pixels
    inside the lids' outline between its 15th and 45th luminance percentiles (darker than the
    sclera, lighter than the pupil and the lashes)."""
    import cv2

    h, w = photo.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    cv2.fillPoly(mask, [np.rint(eye).astype(np.int32)], 1)
    px = photo[mask > 0][:, :3].astype(np.float64)
    if len(px) < 10:
        return np.array([90.0, 70.0, 55.0])
    lum = px @ np.array([0.2126, 0.7152, 0.0722])
    lo, hi = np.percentile(lum, [15, 45])
    sel = (lum >= lo) & (lum <= hi)
    return np.median(px[sel if sel.any() else slice(None)], axis=0)


def surround_image(photo: np.ndarray, face_mask: np.ndarray, *, grow: int = 6, work_side: int = 512) -> np.ndarray:
    """The photograph with the pixels of ``face_mask`` (what the mesh draws, grown by ``grow``
    pixels; shrunk where negative) filled from around them (OpenCV's Telea inpainting at ``work_side`` pixels, the
    filled part enlarged back; the rest of the photograph is kept as it is)."""
    import cv2

    h, w = photo.shape[:2]
    k = min(1.0, work_side / max(h, w))
    small = cv2.resize(np.ascontiguousarray(photo[..., :3]), (max(1, round(w * k)), max(1, round(h * k))),
                       interpolation=cv2.INTER_AREA)
    m = cv2.resize(face_mask.astype(np.uint8) * 255, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST)
    it = round(abs(grow) * k)
    if it:  # grown: a margin filled around the face; shrunk: the face's edge kept under the mesh's
        m = (cv2.dilate if grow > 0 else cv2.erode)(m, np.ones((3, 3), np.uint8), iterations=it)
    filled = cv2.inpaint(small, m, 5, cv2.INPAINT_TELEA)
    big = cv2.resize(filled, (w, h), interpolation=cv2.INTER_CUBIC)
    full = cv2.resize(m, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float64)[..., None] / 255.0
    return np.rint(full * big + (1 - full) * photo[..., :3]).astype(np.uint8)


def wide_blur(image: np.ndarray, sigma: float, step: float = 4.0) -> np.ndarray:
    """A Gaussian blur of ``sigma`` pixels computed at a resolution where it is ``step`` pixels wide,
    then resized back: OpenCV's direct blur of a 2048-pixel frame at sigma 164 took 21 s here, this
    0.05 s, within 2 grey levels of it (mean 0.2; the frame is mirrored first, as the direct blur
    reads past its edges)."""
    import cv2

    f = max(1, int(sigma // step))
    if f == 1:
        return cv2.GaussianBlur(image, (0, 0), sigma)
    h, w = image.shape[:2]
    m = f * int(np.ceil(3 * sigma / f))  # the frame mirrored at full resolution, as the direct blur reads past it
    ph, pw = -h % f, -w % f  # whole f x f blocks: block means sit on the blocks' centres, as resizing back reads them
    full = cv2.copyMakeBorder(np.ascontiguousarray(image), m, m + ph, m, m + pw, cv2.BORDER_REFLECT_101)
    small = cv2.resize(full, (full.shape[1] // f, full.shape[0] // f), interpolation=cv2.INTER_AREA)
    back = cv2.resize(cv2.GaussianBlur(small, (0, 0), sigma / f), (full.shape[1], full.shape[0]),
                      interpolation=cv2.INTER_LINEAR)
    return back[m:m + h, m:m + w]


def padded(image: np.ndarray, share: tuple[float, float, float] = (0.4, 1.2, 0.8), max_side: int = 2048,
           blur: float = 0.08) -> tuple[np.ndarray, tuple[float, float, float]]:
    """``image`` continued by ``share`` (top, bottom, each side) of its size (its border pixels
    repeated, blurred more the farther out (mirrored, clothes made an X below the neckline): a stimulus frame is wider than a portrait, and a
    head-and-shoulders framing reaches below it), at most ``max_side`` pixels; returns the image
    and the padding."""
    import cv2

    h, w = image.shape[:2]
    top, bottom, side = (int(round(f * n)) for f, n in zip(share, (h, h, w)))
    big = cv2.copyMakeBorder(np.ascontiguousarray(image[..., :3]), top, bottom, side, side, cv2.BORDER_REPLICATE)
    k = min(1.0, max_side / max(big.shape[:2]))
    big = cv2.resize(big, (round(big.shape[1] * k), round(big.shape[0] * k)), interpolation=cv2.INTER_AREA)
    soft = wide_blur(big, blur * max(big.shape[:2]))
    yy, xx = np.mgrid[0:big.shape[0], 0:big.shape[1]]
    out_y = np.maximum((top * k - yy) / max(top * k, 1), (yy - (top + h) * k) / max(bottom * k, 1))
    out_x = np.maximum(side * k - xx, xx - (side + w) * k) / max(side * k, 1)
    t = np.clip(np.maximum(out_x, out_y) * 10, 0, 1)[..., None]  # 0 inside, 1 a tenth of the way out
    return np.rint((1 - t) * big + t * soft).astype(np.uint8), tuple(float(f) for f in share)


def surround_corners(camera: OrthoCamera, shape: tuple[int, int], depth: float,
                     pad: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """The model-frame corners ``(4, 3)`` of the plane at camera depth ``depth`` that the
    photograph of ``shape`` covers, padded by ``pad`` (top, bottom, each side) of its size
    (top-left, top-right, bottom-right, bottom-left)."""
    h, w = shape[:2]
    top, bottom, side = pad
    x0, x1, y0, y1 = -side * w, (1 + side) * w, -top * h, (1 + bottom) * h
    return camera.unproject(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]), depth)
