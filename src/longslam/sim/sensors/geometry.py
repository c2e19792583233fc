"""Per-pixel geometry of a depth image that sensor models share: incidence angles, and the
shadow a projector beside the camera casts."""

from __future__ import annotations

import numpy as np

from longslam.core.frame import Intrinsics


def incidence_cos(depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """|cos| of the angle between each pixel's ray and its surface's normal, the normal from the
    cross product of the back-projected neighbours (central differences). 0 where a pixel or a
    neighbour has no return, so a hole's rim and a depth edge count as grazing; the image's
    outermost rows and columns take their inner neighbours' values."""
    k = intrinsics
    h, w = depth.shape
    cos = np.zeros((h, w), np.float32)
    if h < 3 or w < 3:
        return cos
    u = ((np.arange(w, dtype=np.float32) - np.float32(k.cx)) / np.float32(k.fx))[None, :]
    v = ((np.arange(h, dtype=np.float32) - np.float32(k.cy)) / np.float32(k.fy))[:, None]
    z = depth.astype(np.float32, copy=False)
    # Along a row x = z u, y = z v; the differences across a pixel's two neighbours (scaled by 1/2,
    # which the cosine does not see): a = d/du (x, y, z), b = d/dv (x, y, z).
    zl, zr = z[1:-1, :-2], z[1:-1, 2:]
    zt, zb = z[:-2, 1:-1], z[2:, 1:-1]
    uc, vc = u[:, 1:-1], v[1:-1]
    ax, ay, az = zr * u[:, 2:] - zl * u[:, :-2], (zr - zl) * vc, zr - zl
    bx, by, bz = (zb - zt) * uc, zb * v[2:] - zt * v[:-2], zb - zt
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    dot = np.abs(nx * uc + ny * vc + nz)
    norm = np.sqrt((nx * nx + ny * ny + nz * nz) * (uc * uc + vc * vc + 1.0))
    inner = np.divide(dot, norm, out=np.zeros_like(dot), where=norm > 0)
    inner[(zl <= 0) | (zr <= 0) | (zt <= 0) | (zb <= 0) | (z[1:-1, 1:-1] <= 0)] = 0.0
    cos[1:-1, 1:-1] = inner
    cos[0], cos[-1] = cos[1], cos[-2]
    cos[:, 0], cos[:, -1] = cos[:, 1], cos[:, -2]
    return np.where(z > 0, cos, np.float32(0))


def projector_shadow(depth: np.ndarray, intrinsics: Intrinsics, baseline: float) -> np.ndarray:
    """Pixels the camera sees but a projector `baseline` metres to its right (+x) cannot light.

    A point at pixel u with disparity d = baseline * fx / z lands at u - d in the projector's
    image; it is in shadow when a point to its right lands further left there (a nearer surface
    on the same projector ray). So the shadow is a band on the left of every near edge, as wide
    as the two surfaces' disparity difference.
    """
    z = depth.astype(np.float32)
    with np.errstate(divide="ignore"):
        u_projector = np.where(
            z > 0, np.arange(z.shape[1], dtype=np.float32)[None, :] - baseline * intrinsics.fx / z, np.inf
        )
    # The smallest projector column among the pixels to the right of each pixel.
    right_min = np.minimum.accumulate(u_projector[:, ::-1], axis=1)[:, ::-1]
    right_min = np.concatenate([right_min[:, 1:], np.full((z.shape[0], 1), np.inf, np.float32)], axis=1)
    # Pixels are compared at their centres, the edge lies half a pixel beyond the nearer surface's
    # last centre: so "further left" is by more than -0.5 px (a band d_fg - d_bg pixels wide), and
    # a surface lit along its length (each pixel d changing by less than half a pixel) stays lit.
    return (z > 0) & (right_min < u_projector + 0.5)
