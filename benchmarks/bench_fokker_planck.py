"""Fokker–Planck solvers side by side: meanfield against py-pde (and FiPy) on one drift–diffusion problem.

Run:  python benchmarks/bench_fokker_planck.py [--sizes 64,128,256,512] [--reference 2048] [--json FILE]

Problem (published in ``benchmarks/fp_competitors.py``): Ω = [0, 1]², σ = 0.01, drift =
three Gaussian arrow fields (c = 0.5, η = 0.05, fixed positions and angles), uniform
start, zero total flux on the walls, T = 2.

Ours: :class:`~meanfield.FokkerPlanck`, ADI (Peaceman–Rachford) with the accuracy step
``courant=COURANT`` (the drift crosses at most two cells per step, so the O(dt²) time error
scales like the O(h²) space error).  py-pde: explicit Euler at its stability limit h²/(4σ),
numba, one thread.  Measured in one run, on one core, per grid size n:

* **time per solve**: a whole solve to T (ours: coefficients, factorisations and every
  step; py-pde: every step), best of ``--repeats`` runs, ours and py-pde alternately;
* **set-up**: py-pde's grid, equation, numba compilation and first step; ours: grid,
  solver and first step in a fresh Python process, where that step imports numba and
  loads our compiled loops from numba's on-disk cache (and, once, with an empty cache:
  their compilation, the cost of the first run after installing);
* both ratios (py-pde / ours), set-up excluded and included, against the goal
  ``GOAL`` (1.5), which also requires our L² error to be at most py-pde's;
* the L² error ``‖ρ_n - R ρ_ref‖`` of each solver against a fine reference restricted to
  the n² grid by averaging blocks of cells.  The reference is the Richardson extrapolation
  ``(4 ρ_N - ρ_{N/2}) / 3`` of meanfield's ADI on N² and (N/2)² cells (N = ``--reference``,
  dt = 10⁻³), which cancels the schemes' common O(h²) term: it is no solver's own answer.
  It is cached in ``benchmarks/.cache`` (minutes to compute; delete it to recompute).

Also printed, for n <= 256: our other integrators (ADI at the positivity step, split,
explicit) and FiPy when installed; and, at the largest n, the cost of a drift that
changes every step.  Ratios, not raw times, are what to compare across machines.
"""

from __future__ import annotations

import os

from benchmarks.environment import one_thread_variables

one_thread_variables()  # one core

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fp_competitors as comp  # noqa: E402

from benchmarks.records import BENCH_INSTALL, import_error, measured, settings, skipped  # noqa: E402
from meanfield import Domain, FokkerPlanck, GaussianKernel, Grid, NavigationField  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache"
#: our accuracy step: the drift crosses at most COURANT cells per ADI step
COURANT = 2.0
#: speed goal against py-pde, with our L² error at most py-pde's
GOAL = 1.5
#: FiPy takes a minute at 256² (implicit Euler with a sparse solve per step): not run above
FIPY_MAX_CELLS = 256
REFERENCE_DT = 1e-3
OURS_LABEL = f"meanfield FokkerPlanck, ADI, accuracy step courant={COURANT:g}"
PYPDE_SCHEME = "explicit Euler, numba, one thread, dt ~ h^2/(4 sigma)"


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


def meanfield_solve(
    n: int, method: str, dt: float | None, time_dependent: bool = False, courant: float | None = None
) -> dict:
    t0 = time.perf_counter()
    g = grid_for(n)
    fp = FokkerPlanck(g, comp.SIGMA, point_velocity, method=method, time_dependent=time_dependent, courant=courant)
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


_SETUP_CHILD = """
import json, sys, time
sys.path[:0] = [{bench!r}, {root!r}]
import numpy as np
import fp_competitors as comp
from meanfield import Domain, FokkerPlanck, Grid
t0 = time.perf_counter()
g = Grid(Domain.box(1.0, 1.0), cells=({n}, {n}))
fp = FokkerPlanck(g, comp.SIGMA, lambda x, y, t: comp.velocity(x, y), method="adi", time_dependent=False,
                  courant={courant!r})
rho0 = g.normalize(np.ones(g.shape))
fp.step(rho0, 0.0, fp.automatic_dt(rho0))
print(json.dumps(time.perf_counter() - t0))
"""


def ours_setup(n: int, cold: bool = False) -> float:
    """Our set-up in a fresh process: grid, solver, first step (numba import, compiled loops loaded).

    ``cold``: with an empty numba cache (a temporary ``NUMBA_CACHE_DIR``), so the loops compile.
    """
    here = Path(__file__).resolve().parent
    code = _SETUP_CHILD.format(bench=str(here), root=str(here.parent), n=n, courant=COURANT)
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as tmp:
        if cold:
            env["NUMBA_CACHE_DIR"] = tmp
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


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


def reference(n_ref: int, dt: float = REFERENCE_DT) -> np.ndarray:
    """The reference on (n_ref/2)² cells: ``(4 R ρ_{n_ref} - ρ_{n_ref/2}) / 3`` (meanfield ADI at ``dt``)."""
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"fp_reference_richardson_{n_ref}_dt{dt:g}.npy"
    if path.exists():
        return np.load(path)
    print(f"computing the reference from {n_ref}² and {n_ref // 2}² (ADI, dt = {dt:g}); cached in {path}", flush=True)
    fine = meanfield_solve(n_ref, "adi", dt)["rho"]
    coarse = meanfield_solve(n_ref // 2, "adi", dt)["rho"]
    out = (4.0 * restrict(fine, n_ref // 2) - coarse) / 3.0
    tmp = path.with_suffix(".tmp.npy")
    np.save(tmp, out)
    tmp.replace(path)
    return out


def compare(n: int, ref: np.ndarray, repeats: int, pypde: dict | None) -> dict[str, Any]:
    """Ours against py-pde (``pypde``: a prepared :func:`fp_competitors.pypde_solver`, or None) on n².

    Best of ``repeats`` solves each, run alternately (py-pde stops after two once its runs
    add up to a minute); set-up times, errors against ``ref``, both ratios and the verdict.
    """
    meanfield_solve(n, "adi", None, courant=COURANT)  # warm-up: this process loads our compiled loops
    ours_runs, anchor_runs = [], []
    for k in range(repeats):
        ours_runs.append(meanfield_solve(n, "adi", None, courant=COURANT))
        if pypde is not None and (k < 2 or sum(r["wall_time"] for r in anchor_runs) < 60.0):
            anchor_runs.append(pypde["solve"]())
    ours = min(ours_runs, key=lambda r: r["wall_time"])
    exact = restrict(ref, n)
    out: dict[str, Any] = {
        "n": n,
        "ours": {k: ours[k] for k in ("wall_time", "steps", "min", "mass_drift")},
        "ours_rho": ours["rho"],
    }
    out["ours"]["setup_time"] = ours_setup(n)
    out["ours"]["l2_error"] = l2(ours["rho"], exact)
    if pypde is None:
        return out
    anchor = min(anchor_runs, key=lambda r: r["wall_time"])
    a = {k: anchor[k] for k in ("wall_time", "setup_time", "steps", "dt", "solver")}
    a["l2_error"] = l2(anchor["rho"], exact)
    a["mass_drift"] = abs(comp.mass(anchor["rho"]) - 1.0)
    a["min"] = float(anchor["rho"].min())
    o = out["ours"]
    out["anchor"] = a
    out["ratio_excluded"] = a["wall_time"] / o["wall_time"]
    out["ratio_included"] = (a["setup_time"] + a["wall_time"]) / (o["setup_time"] + o["wall_time"])
    out["accurate"] = o["l2_error"] <= a["l2_error"]
    out["repeats"] = {"ours": len(ours_runs), "anchor": len(anchor_runs)}
    return out


def _records_for(row: dict[str, Any], cold: float | None) -> list[dict[str, Any]]:
    """The two py-pde records of one size: set-up excluded, set-up included."""
    n, o, a = row["n"], row["ours"], row["anchor"]
    what = (
        f"Fokker–Planck, three Gaussian arrows, sigma={comp.SIGMA:g}, T={comp.T_FINAL:g}, {n}x{n} cells, "
        "each solver with its own scheme and step"
    )
    goal = f"ratio >= {GOAL:g} and L2 error <= py-pde's"
    errors = f"L2 error vs reference {o['l2_error']:.3g} (ours) vs {a['l2_error']:.3g} (py-pde)"
    steps = f"steps {o['steps']} vs {a['steps']}"
    detail = {k: row[k] for k in ("n", "ours", "anchor", "ratio_excluded", "ratio_included", "accurate", "repeats")}
    detail["cells"] = n
    detail["ours_cold_setup_time"] = cold
    anchor_label = f"py-pde, {PYPDE_SCHEME}"
    excluded = measured(
        "fokker_planck",
        f"fokker_planck {n}^2 vs py-pde",
        what + "; time per solve, set-up excluded",
        OURS_LABEL,
        anchor_label,
        o["wall_time"],
        a["wall_time"],
        "s per solve",
        faster="lower",
        goal=goal,
        passed=row["ratio_excluded"] >= GOAL and row["accurate"],
        note=f"{errors}; {steps}; set-up {o['setup_time']:.2g} s vs {a['setup_time']:.2g} s",
        detail=detail,
    )
    cold_note = f"; ours with an empty numba cache (first run after install): {cold:.2g} s" if cold else ""
    included = measured(
        "fokker_planck",
        f"fokker_planck {n}^2 vs py-pde, set-up included",
        what + "; set-up (ours in a fresh process) plus one solve",
        OURS_LABEL,
        anchor_label,
        o["setup_time"] + o["wall_time"],
        a["setup_time"] + a["wall_time"],
        "s",
        faster="lower",
        goal=goal,
        passed=row["ratio_included"] >= GOAL and row["accurate"],
        note=f"{errors}; set-up {o['setup_time']:.2g} s vs {a['setup_time']:.2g} s{cold_note}",
        detail=detail,
    )
    return [excluded, included]


def _fipy_record(n: int, ours: dict, ref: np.ndarray) -> dict[str, Any]:
    name, label = f"fokker_planck {n}^2 vs FiPy", f"FiPy, implicit Euler, dt = {comp.FIPY_DT:g}"
    what = f"Fokker–Planck, three Gaussian arrows, {n}x{n} cells, time per solve, set-up excluded"
    why = import_error("fipy")
    res = comp.run_fipy(n) if why is None else {"available": False, "reason": why}
    if not res["available"]:
        return skipped(
            "fokker_planck",
            name,
            what,
            OURS_LABEL,
            label,
            f"FiPy not available ({res['reason']}); install: {BENCH_INSTALL}",
        )
    err = l2(res["rho"], restrict(ref, n))
    return measured(
        "fokker_planck",
        name,
        what,
        OURS_LABEL,
        label,
        ours["wall_time"],
        res["wall_time"],
        "s per solve",
        faster="lower",
        note=f"L2 error vs reference {ours['l2_error']:.3g} (ours) vs {err:.3g} (FiPy)",
        detail={"cells": n, "ours": ours, "anchor": {k: res[k] for k in ("wall_time", "setup_time", "steps", "dt")}},
    )


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``fokker_planck`` records of ``meanfield bench`` (``docs/cli.md``): ours against py-pde and FiPy.

    For every size of :data:`benchmarks.records.SETTINGS` (``cells``: 64² quick; 64², 128²,
    256², 512² full): two py-pde records, time per solve with set-up excluded and with it
    included, each with the goal ratio >= 1.5 at an L² error against the reference no
    larger than py-pde's; and a FiPy record up to 256².  An anchor that does not import
    gives a skipped record naming the install command (and nothing is run for it).

    Parameters
    ----------
    quick : bool
        Quick or full settings (``cells``, ``reference``, ``repeats``).

    Returns
    -------
    list of dict
        Per size: py-pde (excluded, included), then FiPy.
    """
    s = settings("fokker_planck", quick)
    sizes = [s["cells"]] if isinstance(s["cells"], int) else list(s["cells"])
    n_ref, repeats = s.get("reference", 512 if quick else 2048), s.get("repeats", 3)
    pde_why, fipy_why = import_error("pde"), import_error("fipy")
    if pde_why is not None and fipy_why is not None:  # nothing to compare with: no solve at all
        records = []
        for n in sizes:
            what = f"Fokker–Planck, three Gaussian arrows, {n}x{n} cells"
            for label, why in (("py-pde", pde_why), ("FiPy", fipy_why)):
                note = f"{label} not available ({why}); install: {BENCH_INSTALL}"
                records.append(
                    skipped("fokker_planck", f"fokker_planck {n}^2 vs {label}", what, OURS_LABEL, label, note)
                )
        return records
    ref = reference(n_ref)
    cold = ours_setup(sizes[0], cold=True)
    records = []
    for n in sizes:
        prepared = comp.pypde_solver(n) if pde_why is None else None
        if prepared is not None and not prepared["available"]:
            pde_why, prepared = prepared["reason"], None
        row = compare(n, ref, repeats, prepared)
        if prepared is None:
            note = f"py-pde not available ({pde_why}); install: {BENCH_INSTALL}"
            what = f"Fokker–Planck, three Gaussian arrows, {n}x{n} cells"
            records.append(skipped("fokker_planck", f"fokker_planck {n}^2 vs py-pde", what, OURS_LABEL, "py-pde", note))
        else:
            records += _records_for(row, cold)
        if n <= FIPY_MAX_CELLS:
            records.append(_fipy_record(n, row["ours"], ref))
    return records


def _variants(n: int, ref: np.ndarray) -> list[tuple[str, dict]]:
    """Our other integrators on n² (and FiPy when installed): label, result."""
    out = [
        ("meanfield adi (positivity dt)", meanfield_solve(n, "adi", None)),
        ("meanfield split dt=1e-3", meanfield_solve(n, "split", 1e-3)),
        ("meanfield explicit (auto dt)", meanfield_solve(n, "explicit", None)),
    ]
    if import_error("fipy") is None:
        out.append(("FiPy implicit", comp.run_fipy(n)))
    return out


def _drift_cost(n: int, dt: float) -> dict[str, Any]:
    fixed = meanfield_solve(n, "adi", dt)["wall_time"]
    redo = meanfield_solve(n, "adi", dt, time_dependent=True)["wall_time"]
    moving = meanfield_moving_robots(n, dt)["wall_time"]
    return {
        "seconds per step, moving drift, adi (tridiagonal sweeps)": per_step_moving(n, "adi", dt, 50),
        "seconds per step, moving drift, implicit (2-D sparse LU each step)": per_step_moving(n, "implicit", dt, 5),
        "n": n,
        "dt": dt,
        "fixed": fixed,
        "re-evaluated velocity": redo,
        "moving robots": moving,
        "ratio re-evaluated/fixed": redo / fixed,
        "ratio moving/fixed": moving / fixed,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="64,128,256,512")
    ap.add_argument("--reference", type=int, default=2048, help="finest grid of the Richardson reference")
    ap.add_argument("--repeats", type=int, default=3, help="solves per solver and size, alternately (best kept)")
    ap.add_argument("--skip-competitors", action="store_true")
    ap.add_argument("--skip-variants", action="store_true", help="only ours (accuracy step) against py-pde")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    ref = reference(args.reference)
    cold = ours_setup(sizes[0], cold=True)
    print(json.dumps({"ours set-up with an empty numba cache (s)": cold}), flush=True)
    rows, others = [], []
    for n in sizes:
        pypde = None if args.skip_competitors else comp.pypde_solver(n)
        row = compare(n, ref, args.repeats, pypde if pypde and pypde["available"] else None)
        row.pop("ours_rho")
        rows.append(row)
        print(json.dumps(row, default=float), flush=True)
        if n <= FIPY_MAX_CELLS and not args.skip_variants:
            for label, res in _variants(n, ref):
                err = l2(res["rho"], restrict(ref, n))
                others.append(
                    {"solver": label, "n": n, "l2_error": err, "wall_time": res["wall_time"], "steps": res.get("steps")}
                )
                print(json.dumps(others[-1]), flush=True)
    drift = None if args.skip_variants else _drift_cost(sizes[-1], 0.01)
    print(f"\nours: ADI courant={COURANT:g}; py-pde: {PYPDE_SCHEME}; goal ratio >= {GOAL:g} at L2 error <= py-pde's")
    print(
        "| n | time per solve ours / py-pde (s) | set-up ours / py-pde (s) | ratio set-up excluded | "
        "ratio set-up included | L2 error ours / py-pde | steps ours / py-pde | goal |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        o, a = r["ours"], r.get("anchor")
        if a is None:
            print(
                f"| {r['n']} | {o['wall_time']:.3g} / - | {o['setup_time']:.2g} / - | - | - | "
                f"{o['l2_error']:.3g} / - | {o['steps']} / - | - |"
            )
            continue
        ok = r["ratio_excluded"] >= GOAL and r["ratio_included"] >= GOAL and r["accurate"]
        print(
            f"| {r['n']} | {o['wall_time']:.3g} / {a['wall_time']:.3g} | {o['setup_time']:.2g} / "
            f"{a['setup_time']:.3g} | {r['ratio_excluded']:.1f} | {r['ratio_included']:.1f} | "
            f"{o['l2_error']:.3g} / {a['l2_error']:.3g} | {o['steps']} / {a['steps']} | {'PASS' if ok else 'FAIL'} |"
        )
    if others:
        print("\n| solver | n | L2 error | wall time (s) | steps |\n|---|---|---|---|---|")
        for r in others:
            print(f"| {r['solver']} | {r['n']} | {r['l2_error']:.3g} | {r['wall_time']:.3g} | {r['steps'] or ''} |")
    if drift is not None:
        print(json.dumps(drift), flush=True)
    if args.json:
        doc = {
            "rows": rows,
            "others": others,
            "drift_cost": drift,
            "ours_cold_setup_time": cold,
            "courant": COURANT,
            "goal": GOAL,
            "reference": args.reference,
            "machine": platform.platform(),
        }
        args.json.write_text(json.dumps(doc, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
