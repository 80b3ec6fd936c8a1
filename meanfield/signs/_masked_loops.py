"""The signs' kernels on the grid's faces with walls hiding them, compiled (eq. (3), plans).

* :func:`masked_face_kernels`: ``K̄`` and its gradient at every face, zero where a wall hides the robot;
* :func:`face_moments`: the face sums the paper's law needs of them (eq. (8)).

Each is paired with its numpy twin, the reference (:mod:`meanfield._compiled`).
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled, inner

__all__ = ["masked_face_kernels", "face_moments"]


# ----------------------------------------------------------------------------- masked kernels
def _masked_face_kernels_numpy(fxf, fyc, fxc, fyf, gxf, gyc, gxc, gyf, sx, sy, out):
    kx, gx_x, gy_x, ky, gx_y, gy_y = out
    np.multiply(fxf[:, :, None] * fyc[:, None, :], sx, out=kx)
    np.multiply(gxf[:, :, None] * fyc[:, None, :], sx, out=gx_x)
    np.multiply(fxf[:, :, None] * gyc[:, None, :], sx, out=gy_x)
    np.multiply(fxc[:, :, None] * fyf[:, None, :], sy, out=ky)
    np.multiply(gxc[:, :, None] * fyf[:, None, :], sy, out=gx_y)
    np.multiply(fxc[:, :, None] * gyf[:, None, :], sy, out=gy_y)
    return out


@inner
def _masked_family(fa, fb, ga, gb, mask, k, gx, gy):
    """One family of faces: ``k = fa fb s``, ``gx = ga fb s``, ``gy = fa gb s`` per robot and face."""
    n, ma, mb = k.shape
    for i in range(n):
        for a in range(ma):
            for b in range(mb):
                s = 1.0 if mask[i, a, b] else 0.0
                k[i, a, b] = fa[i, a] * fb[i, b] * s
                gx[i, a, b] = ga[i, a] * fb[i, b] * s
                gy[i, a, b] = fa[i, a] * gb[i, b] * s


@compiled(fallback=_masked_face_kernels_numpy)
def masked_face_kernels(fxf, fyc, fxc, fyf, gxf, gyc, gxc, gyf, sx, sy, out):
    """``s_i K̄_i`` and ``s_i ∇K̄_i`` on the x-faces and the y-faces from 1-D factors, into ``out``.

    Parameters
    ----------
    fxf, fyc, fxc, fyf : ndarray, shape (n, ·)
        ``c exp(-d²/η)`` along x at the faces / centres (``c`` folded in) and
        ``exp(-d²/η)`` along y at the centres / faces.
    gxf, gyc, gxc, gyf : ndarray
        The same times ``-2d/η`` (the gradient's factors).
    sx, sy : ndarray of bool, shapes (n, nx-1, ny) and (n, nx, ny-1)
        The faces each robot sees.
    out : tuple of 6 ndarray
        ``(K on x-faces, ∂ₓK on x-faces, ∂ᵧK on x-faces, K on y-faces, ∂ₓK, ∂ᵧK on y-faces)``.
    """
    kx, gx_x, gy_x, ky, gx_y, gy_y = out
    _masked_family(fxf, fyc, gxf, gyc, sx, kx, gx_x, gy_x)
    _masked_family(fxc, fyf, gxc, gyf, sy, ky, gx_y, gy_y)
    return out


def _face_moments_numpy(kx, gx_x, gy_x, ky, gx_y, gy_y, Wx, Wy, out):
    for row, (k, W) in enumerate(((kx, Wx), (gx_x, Wx), (gy_x, Wx), (ky, Wy), (gx_y, Wy), (gy_y, Wy))):
        out[row] = np.tensordot(k, W, 2)
    return out


@inner
def _family_moments(k, gx, gy, W, out, row):
    """``Σ_faces K W``, ``Σ ∂ₓK W``, ``Σ ∂ᵧK W`` per robot into ``out[row:row + 3]``."""
    n, ma, mb = k.shape
    for i in range(n):
        s0 = s1 = s2 = 0.0
        for a in range(ma):
            for b in range(mb):
                w = W[a, b]
                s0 += k[i, a, b] * w
                s1 += gx[i, a, b] * w
                s2 += gy[i, a, b] * w
        out[row, i], out[row + 1, i], out[row + 2, i] = s0, s1, s2


@compiled(fallback=_face_moments_numpy)
def face_moments(kx, gx_x, gy_x, ky, gx_y, gy_y, Wx, Wy, out):
    """The six integrals ``Σ_faces K W`` per robot behind ``b_i`` and ``g_i`` (eq. (8)), into ``out`` (6, n).

    Rows: ``K, ∂ₓK, ∂ᵧK`` against ``Wx`` on the x-faces, then against ``Wy`` on the y-faces
    (``W`` = face weight × the face field).
    """
    _family_moments(kx, gx_x, gy_x, Wx, out, 0)
    _family_moments(ky, gx_y, gy_y, Wy, out, 3)
    return out
