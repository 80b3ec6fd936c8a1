"""The sampled navigation field's lattice, compiled: its two matrix products on numba's threads.

For the separable Gaussian kernel ``K̄(ξ) = c exp(-ξ_x²/η) exp(-ξ_y²/η)`` (paper, eq. (3)), ``v_r`` at the
lattice's nodes is two products over the robots (:meth:`meanfield.signs.sampled_field.SampledNavigationField.update`)::

    v_x[a, b] = Σ_i (c cos θ_i Fx[i, a]) Fy[i, b],      v_y[a, b] = Σ_i (c sin θ_i Fx[i, a]) Fy[i, b]

:func:`lattice_products` runs the two side by side, each one call of numpy's own ``dgemm`` with the operands
numpy's ``A.T @ Fy`` passes (:func:`meanfield._compiled.blas.numpy_gemm`): the numbers of its numpy twin to the
bit, on any number of threads.  At the ``stadium``'s 257² nodes and 64 robots the two took 0.39 ms a step in numpy
(on one thread whatever numba's count), 0.18 ms on two threads (issue 45, item 3; docs page *Large crowds*).
"""

from __future__ import annotations

from meanfield._compiled.blas import numpy_gemm
from meanfield._compiled.core import compiled, prange

__all__ = ["lattice_products"]


def _lattice_numpy(ax, ay, fy, vx, vy):
    vx[...] = ax.T @ fy
    vy[...] = ay.T @ fy
    return vx, vy


@compiled(fallback=_lattice_numpy, parallel=True)
def lattice_products(ax, ay, fy, vx, vy):
    """``vx = axᵀ fy`` and ``vy = ayᵀ fy``, side by side on numba's threads, each by numpy's own ``dgemm``.

    Parameters
    ----------
    ax, ay : ndarray, shape (n, mx), C-contiguous
        ``c cos θ_i Fx[i, a]`` and ``c sin θ_i Fx[i, a]``: the robots' weighted x factors at the nodes.
    fy : ndarray, shape (n, my), C-contiguous
        Their y factors.
    vx, vy : ndarray, shape (mx, my), C-contiguous
        Overwritten with the field's components at the nodes.
    """
    n, mx = ax.shape
    my = fy.shape[1]
    no = n < 0  # (not literals: one compilation of numpy_gemm)
    yes = n >= 0
    for t in prange(2):
        if t == 0:
            numpy_gemm(yes, no, mx, my, n, ax, mx, fy, my, vx, my)
        else:
            numpy_gemm(yes, no, mx, my, n, ay, mx, fy, my, vy, my)
    return vx, vy
