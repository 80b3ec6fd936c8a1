"""Competitor Fokker–Planck solvers (FiPy, py-pde) on the shared benchmark problem.

Run:  python benchmarks/fp_competitors.py [n]      (default n = 64)

The problem, identical in every solver:

* Ω = [0, 1]², cell-centred n × n grid, arrays indexed ``[i, j]`` with x along axis 0
  ('ij' indexing), cell centres ``x_i = (i + 0.5) / n``.
* ``∂ₜρ = −∇·(v ρ) + σ Δρ`` with σ = ``SIGMA`` and **zero total flux** through every wall,
  ``n·(v ρ − σ∇ρ) = 0`` (a Robin condition ``σ ∂ₙρ = (v·n) ρ``, since v·n ≠ 0 on walls).
* ``v(x) = Σ_k C exp(−|x − p_k|² / ETA) (cos θ_k, sin θ_k)`` over ``ARROWS = ((p_k, θ_k), …)``.
* ρ₀ ≡ 1 (mass 1), final time ``T_FINAL`` = 2.

How each library imposes the zero-total-flux wall (both are finite-volume schemes whose
wall faces carry no flux, i.e. the discrete form of the Robin condition):

* **FiPy**: ``TransientTerm() == DiffusionTerm(σ) − ExponentialConvectionTerm(v)``, implicit
  Euler, FiPy's default solver.  Exterior faces without constraints carry neither diffusive
  nor convective flux, so the total wall flux is zero.
* **py-pde**: the PDE is written in conservative form,
  ``σ·laplace(ρ) − divergence(v·ρ)``, with a Neumann condition (``derivative = 0``) for the
  Laplacian and a Dirichlet condition (``value = 0``) on the vector field ``v·ρ`` for the
  divergence (``bc_ops={"rho:divergence": ...}``).  py-pde's central divergence on a
  cell-centred grid is the finite-volume divergence with face flux = mean of the two
  neighbouring cells' ``v·ρ``; the Dirichlet ghost cell makes the wall-face value of
  ``(v·ρ)·n`` exactly 0, and the Neumann ghost cell makes the diffusive wall flux exactly 0.
  So every wall face carries zero total flux and mass is conserved to round-off, as in FiPy.
  Explicit Euler (``EulerSolver``, fixed step), numba backend.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

# --------------------------------------------------------------------------- problem
SIGMA = 0.01
C = 0.5
ETA = 0.05
ARROWS: tuple[tuple[tuple[float, float], float], ...] = (
    ((0.30, 0.30), 0.0),
    ((0.70, 0.40), 0.5 * math.pi),
    ((0.45, 0.72), 1.25 * math.pi),
)
T_FINAL = 2.0

#: FiPy's default time step (implicit Euler is unconditionally stable; this is an accuracy choice).
FIPY_DT = 0.01
#: py-pde's explicit step is ``t_final / ceil(t_final / (PYPDE_DT_FRACTION · h² / (4σ))))``.
#: Explicit Euler with the 5-point Laplacian is stable for dt ≤ h²/(4σ); the advection terms
#: (cell Péclet ≤ 0.8 at n = 64) do not tighten this noticeably.  1.0 is stable at n = 64,
#: 128 and 256 (no checkerboard growth); 1.02 already blows up at n = 128 (1.05 at n = 64).
PYPDE_DT_FRACTION = 1.0
#: py-pde's numba multithreading ('never', 'only_local', 'always').  py-pde's default
#: ('only_local') switches threads on for grids with ≥ 256² cells; 'never' keeps every
#: solver on one core so the comparison is like for like.
PYPDE_MULTITHREADING = "never"


def velocity(x, y) -> tuple[np.ndarray, np.ndarray]:
    """The three-arrow velocity field ``(v_x, v_y)`` at points ``(x, y)`` (arrays broadcast)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    vx = np.zeros(np.broadcast(x, y).shape)
    vy = np.zeros_like(vx)
    for (px, py), theta in ARROWS:
        g = C * np.exp(-((x - px) ** 2 + (y - py) ** 2) / ETA)
        vx = vx + g * math.cos(theta)
        vy = vy + g * math.sin(theta)
    return vx, vy


def cell_centres(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell-centre coordinates ``(X, Y)``, each (n, n) in 'ij' layout."""
    xs = (np.arange(n) + 0.5) / n
    return np.meshgrid(xs, xs, indexing="ij")


def mass(rho: np.ndarray) -> float:
    """∫ρ over Ω for a cell-centred (n, n) density."""
    n = rho.shape[0]
    return float(rho.sum() / n**2)


def l2_difference(rho_a: np.ndarray, rho_b: np.ndarray) -> float:
    """Discrete L² distance ``sqrt(Σ (ρ_a − ρ_b)² / n²)``."""
    n = rho_a.shape[0]
    return float(np.sqrt(np.sum((rho_a - rho_b) ** 2) / n**2))


def _steps_for(t_final: float, dt_max: float) -> tuple[float, int]:
    """The largest dt ≤ dt_max that divides t_final into a whole number of steps."""
    steps = max(1, math.ceil(t_final / dt_max - 1e-9))
    return t_final / steps, steps


# --------------------------------------------------------------------------- FiPy
def fipy_to_ij(values: np.ndarray, n: int) -> np.ndarray:
    """FiPy's cell values on ``Grid2D(nx=n, ny=n)`` (x fastest) → (n, n) array indexed [i, j]."""
    return np.asarray(values, dtype=float).reshape(n, n).T.copy()


def run_fipy(n: int, t_final: float = T_FINAL, dt: float | None = None) -> dict:
    """Solve the benchmark problem with FiPy (implicit Euler, exponential convection scheme).

    ``dt`` defaults to ``FIPY_DT`` (0.01); it is shrunk if needed so that a whole number of
    steps reaches ``t_final`` exactly.
    """
    try:
        import fipy
    except Exception as exc:  # ImportError, or a broken install
        return {"available": False, "reason": f"fipy cannot be imported: {exc!r}"}

    dt, steps = _steps_for(t_final, FIPY_DT if dt is None else float(dt))

    t0 = time.perf_counter()
    h = 1.0 / n
    mesh = fipy.Grid2D(dx=h, dy=h, nx=n, ny=n)
    fx, fy = mesh.faceCenters.value
    v = fipy.FaceVariable(mesh=mesh, rank=1, value=np.array(velocity(fx, fy)))
    rho = fipy.CellVariable(mesh=mesh, value=1.0, name="rho")
    eq = fipy.TransientTerm() == fipy.DiffusionTerm(coeff=SIGMA) - fipy.ExponentialConvectionTerm(coeff=v)
    eq.solve(var=rho, dt=dt)  # first step (builds matrices, solver set-up)
    setup_time = time.perf_counter() - t0

    t0 = time.perf_counter()
    for _ in range(steps - 1):
        eq.solve(var=rho, dt=dt)
    wall_time = time.perf_counter() - t0

    return {
        "rho": fipy_to_ij(rho.value, n),
        "wall_time": wall_time,
        "setup_time": setup_time,
        "dt": dt,
        "steps": steps,
        "available": True,
        "solver": f"FiPy {fipy.__version__}, implicit Euler, {type(eq.getDefaultSolver()).__name__}",
    }


# --------------------------------------------------------------------------- py-pde
def pypde_dt(n: int, t_final: float = T_FINAL) -> tuple[float, int]:
    """py-pde's default explicit step for an n × n grid and its number of steps."""
    h = 1.0 / n
    return _steps_for(t_final, PYPDE_DT_FRACTION * h * h / (4.0 * SIGMA))


def pypde_solver(n: int, t_final: float = T_FINAL, dt: float | None = None) -> dict:
    """Set py-pde up once for an n × n grid and return a solver that can be run many times.

    The set-up (timed, ``setup_time``) is what a first solve pays: the grid, the equation,
    the numba stepper (its compilation) and one step on a scratch state.  ``solve()`` then
    runs a whole solve from ρ₀ ≡ 1 to ``t_final`` (every step timed, ``wall_time``) and
    returns the dict of :func:`run_pypde`.  ``{"available": False, "reason": ...}`` when
    py-pde does not import.

    ``dt`` defaults to ``pypde_dt(n)`` ≈ h²/(4σ) (no adaptive stepping); it is shrunk if
    needed so that a whole number of steps reaches ``t_final`` exactly.
    """
    try:
        import pde
    except Exception as exc:  # ImportError, or numba/numpy mismatch
        return {"available": False, "reason": f"py-pde cannot be imported: {exc!r}"}

    if dt is None:
        dt, steps = pypde_dt(n, t_final)
    else:
        dt, steps = _steps_for(t_final, float(dt))

    def threads(value: str) -> str:
        old = pde.config["backend.numba.multithreading"]
        pde.config["backend.numba.multithreading"] = value
        return old

    old_threads = threads(PYPDE_MULTITHREADING)
    try:
        t0 = time.perf_counter()
        grid = pde.CartesianGrid([[0.0, 1.0], [0.0, 1.0]], [n, n])
        X, Y = cell_centres(n)
        v = pde.VectorField(grid, np.array(velocity(X, Y)))
        eq = pde.PDE(
            {"rho": f"{SIGMA!r} * laplace(rho) - divergence(v * rho)"},
            bc={"derivative": 0},  # Laplacian: zero diffusive wall flux
            bc_ops={"rho:divergence": {"value": 0}},  # (v ρ)·n = 0 on the wall face: zero advective flux
            consts={"v": v},
        )
        scratch = pde.ScalarField(grid, 1.0)
        solver = pde.EulerSolver(eq, backend="numba", adaptive=False)
        stepper = solver.make_stepper(scratch, dt)  # numba compilation happens here
        stepper(scratch, 0.0, dt)  # first step
        setup_time = time.perf_counter() - t0
    finally:
        threads(old_threads)
    label = f"py-pde {pde.__version__}, explicit Euler, numba, multithreading={PYPDE_MULTITHREADING}"

    def solve() -> dict:
        old = threads(PYPDE_MULTITHREADING)
        try:
            state = pde.ScalarField(grid, 1.0)
            before = solver.info["steps"]
            t0 = time.perf_counter()
            t = stepper(state, 0.0, t_final)
            wall_time = time.perf_counter() - t0
        finally:
            threads(old)
        taken = solver.info["steps"] - before
        if taken != steps or not math.isclose(t, t_final, rel_tol=1e-9):
            raise RuntimeError(f"py-pde took {taken} steps to t={t}, expected {steps} to {t_final}")
        return {
            "rho": np.array(state.data, dtype=float),  # CartesianGrid data is already [i, j], x along axis 0
            "wall_time": wall_time,
            "setup_time": setup_time,
            "dt": dt,
            "steps": steps,
            "available": True,
            "solver": label,
        }

    return {"available": True, "setup_time": setup_time, "solve": solve, "dt": dt, "steps": steps, "solver": label}


def run_pypde(n: int, t_final: float = T_FINAL, dt: float | None = None) -> dict:
    """Solve the benchmark problem once with py-pde (explicit Euler, numba backend, fixed step).

    ``setup_time``: grid, equation, numba compilation and one step (:func:`pypde_solver`);
    ``wall_time``: a whole solve from t = 0 to ``t_final`` after that.
    """
    prepared = pypde_solver(n, t_final, dt)
    return prepared["solve"]() if prepared["available"] else prepared


# --------------------------------------------------------------------------- main
def _report(name: str, res: dict) -> None:
    if not res["available"]:
        print(f"{name:7s} not available: {res['reason']}")
        return
    rho = res["rho"]
    drift = mass(rho) - 1.0
    print(
        f"{name:7s} dt={res['dt']:.4g} steps={res['steps']} wall={res['wall_time']:.2f}s "
        f"setup={res['setup_time']:.2f}s mass drift={drift:+.2e} min={rho.min():.4f} max={rho.max():.4f}"
    )


def main(n: int = 64) -> None:
    res_fipy = run_fipy(n)
    _report("FiPy", res_fipy)
    res_pypde = run_pypde(n)
    _report("py-pde", res_pypde)
    if res_fipy["available"] and res_pypde["available"]:
        print(f"L2 difference FiPy vs py-pde at n={n}: {l2_difference(res_fipy['rho'], res_pypde['rho']):.3e}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 64)
