"""Fokker–Planck solvers side by side: meanfield, FiPy and py-pde on one drift–diffusion problem.

Run:  python benchmarks/bench_fokker_planck.py [--sizes 64,128,256] [--reference 512] [--json FILE]

Problem (published in ``benchmarks/fp_competitors.py``): Ω = [0, 1]², σ = 0.01, drift =
three Gaussian arrow fields (c = 0.5, η = 0.05, fixed positions and angles), uniform
start, zero total flux on the walls, T = 2.

Measured in one run, on one core:

* the L² error ``‖ρ_n - R ρ_ref‖`` against a ``--reference``² solution (meanfield, ADI at a
  small step), restricted to the n² grid by averaging blocks of cells;
* the wall time of the time stepping, and the set-up time (grid, first step, any
  compilation), for every solver;
* the cost of a time-dependent drift for meanfield's ADI: the same field re-evaluated
  every step (``time_dependent=True``), and robots moving every step (``face_velocity``
  from :class:`~meanfield.robots.NavigationField`), against the fixed field.

The reference is cached in ``benchmarks/.cache`` (it takes minutes); delete it to recompute.
Ratios (py-pde time / meanfield time, FiPy time / meanfield time, moving / fixed) are
what to compare across machines.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fp_competitors as comp  # noqa: E402

from benchmarks.records import BENCH_INSTALL, import_error, measured, settings, skipped  # noqa: E402
from meanfield import Domain, FokkerPlanck, GaussianKernel, Grid, NavigationField  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache"


def grid_for(n: int) -> Grid:
    return Grid(Domain.box(1.0, 1.0), cells=(n, n))


def restrict(fine: np.ndarray, n: int) -> np.ndarray:
    """Average blocks of a fine cell field down to n × n cells (exact for cell averages)."""
    r = fine.shape[0] // n
    return fine.reshape(n, r, n, r).mean(axis=(1, 3))


def l2(a: np.ndarray, b: np.ndarray) -> float:
    n = a.shape[0]
    return float(np.sqrt(((a - b) ** 2).sum() / (n * n)))


def point_velocity(x, y, t):
    return comp.velocity(x, y)


def meanfield_solve(n: int, method: str, dt: float | None, time_dependent: bool = False) -> dict:
    t0 = time.perf_counter()
    g = grid_for(n)
    fp = FokkerPlanck(g, comp.SIGMA, point_velocity, method=method, time_dependent=time_dependent)
    rho0 = g.normalize(np.ones(g.shape))
    setup = time.perf_counter() - t0
    steps = [0]
    t1 = time.perf_counter()
    rho = fp.solve(rho0, comp.T_FINAL, dt=dt, callback=lambda t, r: steps.__setitem__(0, steps[0] + 1))
    wall = time.perf_counter() - t1
    return {
        "rho": rho,
        "wall_time": wall,
        "setup_time": setup,
        "steps": steps[0],
        "min": float(rho.min()),
        "mass_drift": float(abs(g.integrate(rho) - 1.0)),
    }


def meanfield_moving_robots(n: int, dt: float) -> dict:
    """The arrows as robots drifting east at speed 0.05, re-evaluated every step (cost only)."""
    g = grid_for(n)
    kernel = GaussianKernel(comp.C, comp.ETA)
    R = np.array([a[0] for a in comp.ARROWS])
    th = np.array([a[1] for a in comp.ARROWS])
    fp = FokkerPlanck(g, comp.SIGMA, method="adi")
    rho0 = g.normalize(np.ones(g.shape))

    def fv(t):  # a new NavigationField each step: what a closed loop with moving robots does
        return NavigationField(kernel, g, R + np.array([0.05 * t, 0.0]), th).velocity()

    t1 = time.perf_counter()
    rho = fp.solve(rho0, comp.T_FINAL, dt=dt, face_velocity=fv)
    return {"rho": rho, "wall_time": time.perf_counter() - t1}


def per_step_moving(n: int, method: str, dt: float, steps: int) -> float:
    """Seconds per step with robots moving every step (a new drift each step)."""
    g = grid_for(n)
    kernel = GaussianKernel(comp.C, comp.ETA)
    R = np.array([a[0] for a in comp.ARROWS])
    th = np.array([a[1] for a in comp.ARROWS])
    fp = FokkerPlanck(g, comp.SIGMA, method=method)
    rho = g.normalize(np.ones(g.shape))
    t1 = time.perf_counter()
    for k in range(steps):
        fv = NavigationField(kernel, g, R + np.array([0.05 * k * dt, 0.0]), th).velocity()
        rho = fp.step(rho, k * dt, dt, face_velocity=fv)
    return (time.perf_counter() - t1) / steps


def reference(n_ref: int, dt: float) -> np.ndarray:
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"fp_reference_{n_ref}_dt{dt:g}.npy"
    if path.exists():
        return np.load(path)
    print(f"computing the {n_ref}² reference (ADI, dt = {dt:g}); cached in {path}", flush=True)
    out = meanfield_solve(n_ref, "adi", dt)["rho"]
    tmp = path.with_suffix(".tmp.npy")
    np.save(tmp, out)
    tmp.replace(path)
    return out


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``fokker_planck`` records of ``meanfield bench`` (``docs/cli.md``): ours against py-pde and FiPy.

    Our ADI solve (after one untimed warm-up) against each anchor of ``fp_competitors.py``;
    an anchor that does not import or run gives a skipped record naming the install command.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (64² cells; else 128²).

    Returns
    -------
    list of dict
        One record per anchor: py-pde, then FiPy.
    """
    n = settings("fokker_planck", quick)["cells"]
    what = (
        f"Fokker–Planck, three Gaussian arrows, sigma={comp.SIGMA:g}, T={comp.T_FINAL:g}, {n}x{n} cells, "
        "time stepping after set-up, each solver with its own scheme and step"
    )
    ours_label = "meanfield FokkerPlanck, ADI, automatic positivity-preserving step"
    meanfield_solve(n, "adi", None)  # warm-up, as the anchors' first step is set-up
    ours = meanfield_solve(n, "adi", None)
    ours_detail = {k: ours[k] for k in ("wall_time", "setup_time", "steps", "min", "mass_drift")}
    records = []
    for label, module, runner, scheme in (
        ("py-pde", "pde", comp.run_pypde, "explicit Euler, numba, one thread, dt ~ h^2/(4 sigma)"),
        ("FiPy", "fipy", comp.run_fipy, f"implicit Euler, dt = {comp.FIPY_DT:g}"),
    ):
        name = f"fokker_planck {n}^2 vs {label}"
        anchor_label = f"{label}, {scheme}"
        why = import_error(module)
        if why is None:
            res = runner(n)
            if not res["available"]:
                why = res["reason"]
        if why is not None:
            note = f"{label} not available ({why}); install: {BENCH_INSTALL}"
            records.append(skipped("fokker_planck", name, what, ours_label, anchor_label, note))
            continue
        diff = comp.l2_difference(ours["rho"], res["rho"])
        anchor_detail = {k: res[k] for k in ("wall_time", "setup_time", "steps", "dt", "solver")}
        anchor_detail["mass_drift"] = abs(comp.mass(res["rho"]) - 1.0)
        records.append(
            measured(
                "fokker_planck",
                name,
                what,
                ours_label,
                anchor_label,
                ours["wall_time"],
                res["wall_time"],
                "s per solve",
                faster="lower",
                note=(
                    f"L2 difference {diff:.1e}; steps {ours['steps']} vs {res['steps']}; "
                    f"set-up {ours['setup_time']:.2g} s vs {res['setup_time']:.2g} s"
                ),
                detail={"cells": n, "l2_difference": diff, "ours": ours_detail, "anchor": anchor_detail},
            )
        )
    return records


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="64,128,256")
    ap.add_argument("--reference", type=int, default=512)
    ap.add_argument("--reference-dt", type=float, default=1e-4)
    ap.add_argument(
        "--adi-dt",
        type=float,
        default=0.01,
        help="fixed ADI step, run besides the automatic positivity-guaranteeing one (default 0.01)",
    )
    ap.add_argument("--skip-competitors", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    ref = reference(args.reference, args.reference_dt)
    rows = []

    def add(solver: str, n: int, res: dict, note: str = "") -> None:
        if not res.get("available", True):
            rows.append({"solver": solver, "n": n, "note": res.get("reason", "unavailable")})
            return
        err = l2(res["rho"], restrict(ref, n))
        row = {
            "solver": solver,
            "n": n,
            "l2_error": err,
            "wall_time": res["wall_time"],
            "setup_time": res.get("setup_time"),
            "steps": res.get("steps"),
            "dt": res.get("dt"),
            "note": note,
        }
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if v is not None}), flush=True)

    for n in sizes:
        add("meanfield adi (auto dt)", n, meanfield_solve(n, "adi", None))
        if args.adi_dt:
            add(f"meanfield adi dt={args.adi_dt:g}", n, meanfield_solve(n, "adi", args.adi_dt))
        add("meanfield split dt=1e-3", n, meanfield_solve(n, "split", 1e-3))
        add("meanfield explicit (auto dt)", n, meanfield_solve(n, "explicit", None))
        if not args.skip_competitors:
            add("py-pde explicit", n, comp.run_pypde(n))
            add("FiPy implicit", n, comp.run_fipy(n))
    n = sizes[-1]
    dt = args.adi_dt or 1e-3
    fixed = meanfield_solve(n, "adi", dt)["wall_time"]
    redo = meanfield_solve(n, "adi", dt, time_dependent=True)["wall_time"]
    moving = meanfield_moving_robots(n, dt)["wall_time"]
    adi_step = per_step_moving(n, "adi", dt, 50)
    lu_step = per_step_moving(n, "implicit", dt, 5)
    drift_cost = {
        "seconds per step, moving drift, adi (tridiagonal sweeps)": adi_step,
        "seconds per step, moving drift, implicit (2-D sparse LU each step)": lu_step,
        "n": n,
        "dt": dt,
        "fixed": fixed,
        "re-evaluated velocity": redo,
        "moving robots": moving,
        "ratio re-evaluated/fixed": redo / fixed,
        "ratio moving/fixed": moving / fixed,
    }
    print(json.dumps(drift_cost), flush=True)
    print("\n| solver | n | L2 error | wall time (s) | set-up (s) | steps |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        if "l2_error" in r:
            print(
                f"| {r['solver']} | {r['n']} | {r['l2_error']:.3g} | {r['wall_time']:.3g} | "
                f"{(r['setup_time'] or 0):.3g} | {r['steps'] or ''} |"
            )
        else:
            print(f"| {r['solver']} | {r['n']} | {r['note']} | | | |")
    print(
        f"\ntime-dependent drift at {n}², ADI dt={dt:g}: re-evaluated/fixed = {redo / fixed:.2f}, "
        f"moving robots/fixed = {moving / fixed:.2f}"
    )
    print(
        f"moving drift at {n}², seconds per step: adi {adi_step:.4f}, 2-D LU refactorised each step "
        f"{lu_step:.4f} (ratio {lu_step / adi_step:.1f})"
    )
    if args.json:
        args.json.write_text(
            json.dumps(
                {"rows": rows, "drift_cost": drift_cost, "machine": platform.platform()}, indent=2, default=float
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
