"""``meanfield study controllers SCENARIO``: every installed controller on the same seeds, side by side.

Each controller (and the paper's law with the bounded β/γ program, where it is installed)
runs the scenario for the same seeds as one sweep (:func:`meanfield.workflows.sweep.run_sweep`: Dask,
resumable, ``OUT/<controller>/runs/*.json``).  The study then writes, per controller, the
**median and the worst seed** of the objective (the fraction in the target region, or the
fraction evacuated when the room has exits), the time to 90 % in the target (or to 95 %
out), the final ``‖ρ̃‖`` ratio and W₂ to the target, the share of steps at a speed limit,
the compute per control step and its ratio to the paper's law in the same study, and the
stragglers (humans no sign reached in the last half of the run, :mod:`meanfield.simulation.stragglers`):

    OUT/controllers.md    the table (markdown)
    OUT/controllers.csv   the same, one row per controller
    OUT/controllers.png   median and worst seed of the objective; compute per step

Exit status: 0 when every run completed, 1 when one did not (the outputs are written), 2 on
bad input (an unknown controller, a bad seed list), before anything runs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["study_controllers", "candidates", "table"]


def reference_law() -> tuple[str, str]:
    """The study's reference, against which each controller's compute is measured, and its β/γ rule:
    the scenario's default controller and rule (the paper's law, minimum-norm)."""
    from meanfield.scenarios.sections import ControllerSpec  # the scenario's defaults (a lazy import: --help)

    return ControllerSpec.kind, ControllerSpec.beta_gamma


def candidates(scenario: Any, sensing: float | None = None) -> dict[str, dict[str, Any]]:
    """Every installed controller that applies to ``scenario``: ``{label: scenario overrides}``.

    The registered controllers by name (those whose record says ``requires_exits``, such as
    ``evacuation``, only in a room with exits), and the paper's law (:func:`reference_law`) with each other
    registered β/γ rule (``backstepping+bounded`` when :mod:`analysis.bounded` is installed).
    With ``sensing = r``, each controller that runs on local knowledge (its record's
    ``accepts_sensing``) gets a twin ``<name>@r`` whose robots see within ``r`` and talk within
    ``2 r`` (:mod:`meanfield.controllers.local_sensing`).
    """
    from meanfield import plugins
    from meanfield.geometry.exits import exit_segments

    exits = len(exit_segments(scenario.domain)) > 0
    law, default_rule = reference_law()
    out: dict[str, dict[str, Any]] = {}
    for name in plugins.available("controller"):
        can = plugins.capabilities("controller", name)
        if can.requires_exits and not exits:
            continue
        out[name] = {"controller.kind": name}
        if name == law:
            for rule in plugins.available("beta_gamma"):
                if rule != default_rule:
                    out[f"{law}+{rule}"] = {"controller.kind": law, "controller.beta_gamma": rule}
        if sensing is not None and can.accepts_sensing:
            local = {"sensing.radius": sensing, "sensing.comm_radius": 2 * sensing}
            out[f"{name}@{sensing:g}"] = {"controller.kind": name, **local}
    return out


def _pick(ds: Any, key: str) -> np.ndarray:
    return np.asarray(ds[key].values, float).ravel() if key in ds else np.full(1, np.nan)


def _row(label: str, ds: Any, exits: bool) -> dict[str, Any]:
    """The figures of one controller's sweep (NaN where a run did not finish or a time was not reached)."""
    objective = _pick(ds, "fraction_evacuated" if exits else "fraction_in_target")
    reach = _pick(ds, "evacuation_time_95" if exits else "time_to_90")
    reach = np.where(np.isnan(reach), np.inf, reach)  # not reached within the run
    per_step = 1e3 / _pick(ds, "steps_per_second")
    stragglers = _pick(ds, "stragglers")
    done = np.asarray(ds["status"].values).ravel() == "completed"
    return {
        "controller": label,
        "seeds": int(done.sum()),
        "objective_median": float(np.nanmedian(objective)),
        "objective_worst": float(np.nanmin(objective)),
        "time_median": float(np.median(reach)),
        "time_worst": float(np.max(reach)),
        "l2_ratio_median": float(np.nanmedian(_pick(ds, "l2_error_ratio"))),
        "w2_median": float(np.nanmedian(_pick(ds, "w2_to_target_final"))),
        "at_limit_median": float(np.nanmedian(_pick(ds, "limits_binding_fraction"))),
        "ms_per_step": float(np.nanmedian(per_step)),
        "stragglers_median": float(np.nanmedian(stragglers)) if np.isfinite(stragglers).any() else math.nan,
        "stragglers_worst": float(np.nanmax(stragglers)) if np.isfinite(stragglers).any() else math.nan,
    }


def study_controllers(
    scenario: Any,
    seeds: int | Sequence[int],
    out_dir: str | Path,
    *,
    controllers: Sequence[str] | None = None,
    sensing: float | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Run every controller (or ``controllers``) on ``scenario`` for ``seeds``; write the table and figure.

    Parameters
    ----------
    scenario : Scenario or str or Path
        A scenario, a built-in name or a TOML file.
    seeds : int or sequence of int
        ``N`` for seeds ``0..N-1``, or the seeds.
    out_dir : str or Path
        Where each controller's sweep and the study's table and figure go.
    controllers : sequence of str, optional
        Labels among :func:`candidates` (default: all of them).
    sensing : float, optional
        Add each controller's twin with a sensing radius (and twice that to talk): ``<name>@r``.
    workers : int, optional
        Worker processes of the local Dask cluster.
    progress : bool
        Progress bars.

    Returns
    -------
    list of dict
        One row per controller (the columns of ``controllers.csv``).

    Raises
    ------
    ParameterError
        Before any run: a controller that is not installed or does not apply.
    """
    from meanfield.geometry.exits import exit_segments
    from meanfield.scenarios.scenario import load_scenario
    from meanfield.workflows.dask_cluster import jobs_on
    from meanfield.workflows.sweep import run_sweep

    base = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario
    if sensing is not None and not (isinstance(sensing, (int, float)) and math.isfinite(sensing) and sensing > 0):
        raise ParameterError("--sensing", sensing, "a sensing radius > 0")
    known = candidates(base, sensing)
    chosen = list(known) if controllers is None else list(controllers)
    for name in chosen:
        if name not in known:
            raise ParameterError("--controllers", name, f"controllers among {sorted(known)}")
    if not chosen:
        raise ParameterError("--controllers", "none", f"at least one of {sorted(known)}")
    exits = len(exit_segments(base.domain)) > 0
    out = Path(out_dir)
    rows, statuses = [], []
    with jobs_on(None, workers):  # one cluster for every controller's sweep, started at the first
        for name in chosen:
            sets = {key: [value] for key, value in known[name].items()}
            ds = run_sweep(base, sets, seeds, out / name, workers=workers, progress=progress)
            statuses.append(ds.attrs["status"])
            rows.append(_row(name, ds, exits))
    law = next((r["ms_per_step"] for r in rows if r["controller"] == reference_law()[0]), math.nan)
    for r in rows:
        r["compute_vs_law"] = r["ms_per_step"] / law if law > 0 else math.nan
    _write(rows, out, exits, base.name)
    if any(s != "completed" for s in statuses):
        raise _Incomplete(rows)
    return rows


class _Incomplete(Exception):
    """Some run did not complete (the table and figure are written)."""

    def __init__(self, rows: list[dict[str, Any]]):
        super().__init__("a run of the study did not complete")
        self.rows = rows


def _fmt_time(x: float) -> str:
    return "not reached" if not math.isfinite(x) else f"{x:.3g}"


def table(rows: list[dict[str, Any]], exits: bool) -> str:
    """The markdown table of the study."""
    what = "fraction evacuated" if exits else "fraction in target"
    when = "time to 95 % out" if exits else "time to 90 %"
    lines = [
        f"| controller | seeds | {what}, median | worst seed | {when}, median (worst) | ‖ρ̃‖ ratio | W₂ |"
        " steps at a limit | ms / step | ÷ law | stragglers, median (worst) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        strag = "—" if math.isnan(r["stragglers_median"]) else f"{r['stragglers_median']:g} ({r['stragglers_worst']:g})"
        lines.append(
            f"| {r['controller']} | {r['seeds']} | {r['objective_median']:.3f} | {r['objective_worst']:.3f} |"
            f" {_fmt_time(r['time_median'])} ({_fmt_time(r['time_worst'])}) | {r['l2_ratio_median']:.3g} |"
            f" {r['w2_median']:.3g} | {r['at_limit_median']:.0%} | {r['ms_per_step']:.3g} |"
            f" {r['compute_vs_law']:.2g} | {strag} |"
        )
    return "\n".join(lines)


def _write(rows: list[dict[str, Any]], out: Path, exits: bool, name: str) -> None:
    import csv
    import io

    from meanfield.io.atomic import atomic_write_text, save_figure, subplots

    atomic_write_text(out / "controllers.md", table(rows, exits) + "\n")
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(out / "controllers.csv", buf.getvalue())
    fig, (a0, a1) = subplots(1, 2, figsize=(11, 3.8), constrained_layout=True)
    x = np.arange(len(rows))
    labels = [r["controller"] for r in rows]
    a0.bar(x - 0.2, [r["objective_median"] for r in rows], 0.4, label="median")
    a0.bar(x + 0.2, [r["objective_worst"] for r in rows], 0.4, label="worst seed")
    a0.set(
        xticks=x,
        ylim=(0, 1.02),
        ylabel="fraction evacuated" if exits else "fraction in target",
        title=f"{name}: outcome per controller",
    )
    a0.set_xticklabels(labels, rotation=20, ha="right")
    a0.legend(loc="lower right", fontsize=8)
    a1.bar(x, [r["ms_per_step"] for r in rows], 0.6, color="tab:gray")
    a1.set(xticks=x, yscale="log", ylabel="compute per control step (ms, median)", title="cost")
    a1.set_xticklabels(labels, rotation=20, ha="right")
    save_figure(fig, out / "controllers.png")
