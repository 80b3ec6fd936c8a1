"""The humans' pairwise interaction: the potential ``W`` and the mean interaction velocity ``u_W`` evaluated through
the grid (never O(N²)).

Microscopic (paper, eq. (1)):   ``u_W(X_j) = (1/N) Σ_k ∇W(X_k - X_j)``
Mean-field limit:               ``u_W[ρ](x) = ∫_Ω ∇W(y - x) ρ(y) dy``

The paper's PDE (eq. (4)) writes ``∇W * ρ`` = ``∫ ∇W(x - y) ρ(y) dy``, which for an even
``W`` (odd ``∇W``) is the *opposite* sign.  The toolkit derives the PDE from the SDE and
uses ``u_W[ρ]`` above everywhere (crowd, Fokker–Planck drift, and ``v_d``).

Both forms are a discrete convolution of cell masses with ``∇W`` sampled at the offsets
between cell centres (or between cell centres and faces), done once per call by FFT on a
zero-padded (non-periodic) grid; the kernels' transforms are computed once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from scipy import fft as sfft

from meanfield.errors import ParameterError, positive_number
from meanfield.geometry.grid import FaceField, Grid, linear_binning

__all__ = ["InteractionField", "InteractionPotential", "GaussianPotential"]


@runtime_checkable
class InteractionPotential(Protocol):
    """Pairwise potential W between humans; the SDE drift is ``(1/N) Σ_k ∇W(X_k - X_j)``."""

    def gradient(self, z_x: Any, z_y: Any) -> tuple[np.ndarray, np.ndarray]:
        """∇W at ``z``."""
        ...


@dataclass(frozen=True)
class GaussianPotential:
    """``W(z) = s exp(-|z|²/ℓ²)``; ``s > 0`` repels, ``s < 0`` attracts.

    With the SDE's convention ``(1/N) Σ_k ∇W(X_k - X_j)``, ``∇W(X_k - X_j)`` points from
    ``X_k`` towards ``X_j`` when ``s > 0``: human ``j`` is pushed away from ``k``.

    Parameters
    ----------
    strength : float
        ``s`` (any finite non-zero value).
    length : float
        ``ℓ > 0``.
    """

    strength: float
    length: float

    def __post_init__(self) -> None:
        s = float(self.strength)
        if not math.isfinite(s):
            raise ParameterError("interaction.strength", s, "a finite number")
        object.__setattr__(self, "strength", s)
        object.__setattr__(self, "length", positive_number("interaction.length", self.length))

    def value(self, z_x: Any, z_y: Any) -> np.ndarray:
        """``W(z)``."""
        return self.strength * np.exp(-(z_x * z_x + z_y * z_y) / self.length**2)

    def gradient(self, z_x: Any, z_y: Any) -> tuple[np.ndarray, np.ndarray]:
        """``∇W(z) = -(2/ℓ²) z W(z)``."""
        w = self.value(z_x, z_y)
        s = -2.0 / self.length**2
        return s * z_x * w, s * z_y * w


class _Convolver:
    """Linear map ``m -> out[a] = Σ_c m[c] k(y_c - x_a)`` on a regular lattice, by FFT."""

    def __init__(self, kernel_at_offsets, shape_in, shape_out, shift):
        nx, ny = shape_in
        mx, my = shape_out
        sx, sy = shift  # output point a = (i, j) sits at centre offset (i + sx, j + sy)
        # offsets y_c - x_a = (c_i - a_i - sx, c_j - a_j - sy) for c_i - a_i in [-(mx-1), nx-1]
        di = np.arange(-(mx - 1), nx)
        dj = np.arange(-(my - 1), ny)
        self.k = kernel_at_offsets(di - sx, dj - sy)  # list of arrays (len(di), len(dj))
        self.shape_in = shape_in
        self.shape_out = shape_out
        full = (nx + len(di) - 1, ny + len(dj) - 1)  # no wrap-around: zero padding
        self.fshape = tuple(sfft.next_fast_len(s, real=True) for s in full)
        # correlation out[a] = Σ_c m[c] k[c - a]: convolve m with k reversed
        self.kf = [sfft.rfft2(kk[::-1, ::-1], self.fshape) for kk in self.k]

    def __call__(self, m: np.ndarray) -> list[np.ndarray]:
        if np.iscomplexobj(m):  # linear map: real and imaginary parts separately
            re, im = self(m.real), self(m.imag)
            return [a + 1j * b for a, b in zip(re, im, strict=True)]
        mf = sfft.rfft2(m, self.fshape)
        nx, ny = self.shape_in
        mx, my = self.shape_out
        # out[a] = sum_c m[c] K[c - a + mx - 1] = (m * K_reversed)[a + n - 1]
        return [sfft.irfft2(mf * kf, self.fshape)[nx - 1 : nx - 1 + mx, ny - 1 : ny - 1 + my] for kf in self.kf]


class InteractionField:
    """``u_W`` on cells, faces and at agents for a potential ``W`` on ``grid``.

    Parameters
    ----------
    grid : Grid
    potential : InteractionPotential
        Provides ``gradient(z_x, z_y)``.
    """

    def __init__(self, grid: Grid, potential: InteractionPotential):
        self.grid = grid
        self.potential = potential
        dx, dy = grid.dx, grid.dy

        def grad_at(si, sj):
            zx = si[:, None] * dx + 0.0 * sj[None, :]
            zy = 0.0 * si[:, None] + sj[None, :] * dy
            gx, gy = potential.gradient(zx, zy)
            return [np.asarray(gx, float), np.asarray(gy, float)]

        nx, ny = grid.shape
        self._cells = _Convolver(grad_at, (nx, ny), (nx, ny), (0.0, 0.0))
        self._xfaces = _Convolver(lambda a, b: grad_at(a, b)[:1], (nx, ny), (nx - 1, ny), (0.5, 0.0))
        self._yfaces = _Convolver(lambda a, b: grad_at(a, b)[1:], (nx, ny), (nx, ny - 1), (0.0, 0.5))

    def on_cells(self, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``u_W[ρ]`` at the cell centres (both components)."""
        gx, gy = self._cells(rho * self.grid.volume)
        return gx, gy

    def on_faces(self, rho: np.ndarray) -> FaceField:
        """``u_W[ρ]`` on the faces (normal components), as the Fokker–Planck drift needs."""
        m = rho * self.grid.volume
        return self._xfaces(m)[0], self._yfaces(m)[0]

    def at_points(self, points: np.ndarray) -> np.ndarray:
        """``(1/N) Σ_k ∇W(X_k - X_j)`` at every agent, through the grid: O(N + G log G).

        The agents are binned (linear weights) into cell masses, ``u_W`` is computed at
        the cell centres by FFT and interpolated back bilinearly.
        """
        g = self.grid
        x0, _, y0, _ = g.domain.bounds
        m = linear_binning(points, (x0, y0), (g.dx, g.dy), g.shape, 1.0 / len(points))
        gx, gy = self._cells(m)
        return np.column_stack([g.interpolate(gx, points), g.interpolate(gy, points)])
