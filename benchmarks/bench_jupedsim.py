"""JuPedSim crowd backend against JuPedSim alone, measured in the same run, on one core.

Run:  python benchmarks/bench_jupedsim.py [--quick] [--repeats 3] [--json FILE] [--out FILE]

Scenario, at N = 200, 2,000 and 10,000 agents (``--quick``: 200 and 2,000, fewer steps): a
150 × 150 m square room, the collision-free speed model, JuPedSim time step 0.05 s, bodies of
radius 0.2 m placed without overlap by :func:`meanfield.crowds.jupedsim_engine.place_bodies` (the
same positions for every measurement at a given N).

* Anchor: JuPedSim's own engine without steering.  The simulation is built as
  :class:`meanfield.crowds._jupedsim_api.JuPedSimAdapter` builds it (direct-steering stage, one
  journey, the agents added one by one), but with JuPedSim's public API only; each agent gets
  one fixed target once, then ``sim.iterate()`` is timed over S steps.
* Ours: :class:`meanfield.crowds.jupedsim_engine.JuPedSimEngine` stepped with
  ``crowd.step(velocity, t, dt=0.05)``, one JuPedSim step per control period, so every agent
  is steered at every step.  The desired velocities are a fixed random field rotated by
  0.01 rad per step, its magnitudes modulated by ±20 % (every uncapped speed changes every
  step), precomputed (their making is not timed).
* Pieces: the body of ``crowd.step`` replayed with a clock around each call
  (``steering_targets``, ``adapter.steer``, ``adapter.iterate``, ``adapter.positions``), to
  show where the adapter's time goes.

Each repeat, at every N, builds the three simulations (not timed) and runs them in turns,
a tenth of the S steps at a time (interleaved: same process, same machine load); the figures
are the best of ``--repeats`` (each repeat's time per step over its S steps).  The adapter's Python overhead
per agent-step is (ours − anchor time per step) / N, checked against the target of 1.5 µs.
The ratio ours / anchor (time per step) is what to compare across machines.

``--json`` writes the figures as JSON, ``--out`` the printed report as text.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from typing import TYPE_CHECKING, Any  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.records import import_error, measured, settings, skipped  # noqa: E402
from benchmarks.reporting import write_files  # noqa: E402
from meanfield import Domain  # noqa: E402
from meanfield.crowds.jupedsim_engine import JuPedSimEngine, place_bodies  # noqa: E402

if TYPE_CHECKING:  # imported where used: the suite's adapter imports this module without JuPedSim
    import jupedsim as jps

SIDE = 150.0  # room side (m)
RADIUS = 0.2  # body radius (m)
MAX_SPEED = 1.34  # desired-speed cap (m/s)
DT = 0.05  # JuPedSim step = control period (s)
TURN = 0.01  # rotation of the desired-velocity field per step (rad)
TARGET_OVERHEAD_US = 1.5  # the target: adapter overhead per agent-step (µs)
FULL_STEPS = {200: 2000, 2000: 400, 10000: 100}
QUICK_STEPS = {200: 300, 2000: 60}
CHUNKS = 10  # slices in which anchor, ours and pieces take turns
PIECES = ("steering_targets", "steer", "iterate", "positions")


def velocity_fields(n: int, steps: int, seed: int) -> list[np.ndarray]:
    """``steps`` desired-velocity arrays (n, 2): one random field, rotated by TURN per step,
    its magnitudes modulated by ±20 % so that every uncapped speed changes at every step (as
    the followers' |v_r| does in the closed loop; the adapter only sends changed speeds)."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    speed = rng.uniform(0.5, 1.6, n)  # some above MAX_SPEED, to exercise the cap
    phase = rng.uniform(0.0, 2.0 * np.pi, n)
    out = []
    for k in range(steps):
        a = angle + TURN * k
        m = speed * (1.0 + 0.2 * np.sin(0.05 * k + phase))
        out.append(np.ascontiguousarray(np.column_stack([m * np.cos(a), m * np.sin(a)])))
    return out


def build_anchor(positions: np.ndarray, domain: Domain, seed: int) -> jps.Simulation:
    """JuPedSim alone, built as the adapter builds it, with one fixed target per agent set once."""
    import jupedsim as jps

    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=domain.to_shapely(resolution=256), dt=DT)
    stage = sim.add_direct_steering_stage()
    journey = sim.add_journey(jps.JourneyDescription([stage]))
    ids = [
        sim.add_agent(
            jps.CollisionFreeSpeedModelAgentParameters(
                position=(x, y), journey_id=journey, stage_id=stage, desired_speed=MAX_SPEED, radius=RADIUS
            )
        )
        for x, y in positions.tolist()
    ]
    rng = np.random.default_rng(seed)
    targets = rng.uniform(RADIUS, SIDE - RADIUS, (len(ids), 2))  # random points of the room
    for i, (x, y) in zip(ids, targets.tolist(), strict=True):
        sim.agent(i).target = (x, y)
    sim.iterate()  # warm-up, as for ours
    return sim


def build_crowd(positions: np.ndarray, domain: Domain, velocities: list[np.ndarray]) -> JuPedSimEngine:
    crowd = JuPedSimEngine(positions, domain, radius=RADIUS, max_speed=MAX_SPEED, time_step=DT)
    crowd.step(velocities[0], 0.0, dt=DT)  # warm-up
    return crowd


def anchor_chunk(sim: jps.Simulation, count: int) -> float:
    """Seconds for ``count`` steps of JuPedSim alone."""
    t0 = time.perf_counter()
    sim.iterate(count)
    return time.perf_counter() - t0


def ours_chunk(crowd: JuPedSimEngine, velocities: list[np.ndarray], first: int, count: int) -> float:
    """Seconds for ``count`` calls of ``JuPedSimEngine.step`` (one JuPedSim step each)."""
    step = crowd.step
    t0 = time.perf_counter()
    for k in range(first, first + count):
        step(velocities[k], k * DT, dt=DT)
    return time.perf_counter() - t0


def pieces_chunk(crowd: JuPedSimEngine, velocities: list[np.ndarray], first: int, count: int) -> dict[str, float]:
    """The body of ``JuPedSimEngine.step`` replayed ``count`` times with a clock around each call."""
    adapter = crowd.adapter
    clock = time.perf_counter
    total = dict.fromkeys(PIECES, 0.0)
    for k in range(first, first + count):
        t0 = clock()
        targets, speeds = crowd.steering_targets(velocities[k], DT)
        t1 = clock()
        adapter.steer(targets, speeds)
        t2 = clock()
        adapter.iterate(1)
        t3 = clock()
        adapter.positions(out=crowd.positions)
        t4 = clock()
        total["steering_targets"] += t1 - t0
        total["steer"] += t2 - t1
        total["iterate"] += t3 - t2
        total["positions"] += t4 - t3
    return total


def one_repeat(positions: np.ndarray, domain: Domain, velocities: list[np.ndarray], steps: int, seed: int) -> dict:
    """Anchor, ours and pieces on three live simulations, alternated in CHUNKS slices of the steps."""
    sim = build_anchor(positions, domain, seed)
    ours = build_crowd(positions, domain, velocities)
    timed = build_crowd(positions, domain, velocities)
    t_anchor = t_ours = 0.0
    pieces = dict.fromkeys(PIECES, 0.0)
    bounds = np.linspace(1, steps + 1, CHUNKS + 1).round().astype(int)
    for first, stop in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
        count = stop - first
        t_anchor += anchor_chunk(sim, count)
        t_ours += ours_chunk(ours, velocities, first, count)
        for k, v in pieces_chunk(timed, velocities, first, count).items():
            pieces[k] += v
    return {
        "anchor_s": t_anchor / steps,
        "ours_s": t_ours / steps,
        "pieces_s": {k: v / steps for k, v in pieces.items()},
    }


def measure(plan: dict[int, int], repeats: int) -> tuple[list[dict], list[dict]]:
    """Best of ``repeats`` for each ``{N: steps}`` of ``plan``: the per-N results and every run."""
    domain = Domain.box(SIDE, SIDE)
    setup = {}
    for n, steps in plan.items():
        rng = np.random.default_rng(n)
        positions = place_bodies(lambda k, rng=rng: domain.sample_uniform(k, rng), n, RADIUS, domain)
        setup[n] = (positions, velocity_fields(n, steps + 1, seed=n + 1))

    best: dict[int, dict] = {n: {"anchor": np.inf, "ours": np.inf, **dict.fromkeys(PIECES, np.inf)} for n in plan}
    runs = []
    for r in range(repeats):
        for n, steps in plan.items():
            positions, velocities = setup[n]
            run = one_repeat(positions, domain, velocities, steps, seed=n + 2)
            runs.append({"repeat": r, "n": n, "steps": steps, **run})
            anchor, ours, pieces = run["anchor_s"], run["ours_s"], run["pieces_s"]
            b = best[n]
            b["anchor"], b["ours"] = min(b["anchor"], anchor), min(b["ours"], ours)
            for k in PIECES:
                b[k] = min(b[k], pieces[k])

    us = 1e6
    results = []
    for n, steps in plan.items():
        b = best[n]
        overhead = (b["ours"] - b["anchor"]) / n * us
        adapter_pieces = {k: b[k] / n * us for k in ("steering_targets", "steer", "positions")}
        results.append(
            {
                "n": n,
                "steps": steps,
                "anchor_steps_per_second": 1.0 / b["anchor"],
                "anchor_us_per_agent_step": b["anchor"] / n * us,
                "ours_steps_per_second": 1.0 / b["ours"],
                "ours_us_per_agent_step": b["ours"] / n * us,
                "ratio_ours_over_anchor_time": b["ours"] / b["anchor"],
                "overhead_us_per_agent_step": overhead,
                "pieces_us_per_agent_step": {**adapter_pieces, "iterate": b["iterate"] / n * us},
                "pieces_overhead_us_per_agent_step": sum(adapter_pieces.values()),
                "dominant_piece": max(adapter_pieces, key=adapter_pieces.__getitem__),
                "pass": bool(overhead <= TARGET_OVERHEAD_US),
            }
        )
    return results, runs


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``jupedsim`` records of ``meanfield bench`` (``docs/cli.md``): ours against JuPedSim alone.

    Without JuPedSim (it does not import), one skipped record naming the install command,
    and nothing is measured.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        One record per number of agents of :func:`measure`, with the goal :data:`TARGET_OVERHEAD_US`.
    """
    s = settings("jupedsim", quick)
    plan = {int(k): int(v) for k, v in s["steps"].items()}
    what = "JuPedSimEngine.step (JuPedSim backend, every agent steered every step) in a 150x150 m room"
    ours_label = "meanfield JuPedSimEngine, JuPedSim backend, steps/s"
    anchor_label = "JuPedSim alone (sim.iterate, one fixed target per agent), steps/s"
    why = import_error("jupedsim")
    if why is not None:
        from meanfield.crowds._jupedsim_api import INSTALL_HINT

        note = f"jupedsim not available ({why}); install: {INSTALL_HINT}"
        return [skipped("jupedsim", "jupedsim vs JuPedSim alone", what, ours_label, anchor_label, note)]
    results, _ = measure(plan, s["repeats"])
    target = TARGET_OVERHEAD_US
    return [
        measured(
            "jupedsim",
            f"jupedsim N={x['n']} vs JuPedSim alone",
            f"{what}, N={x['n']}, {x['steps']} steps",
            ours_label,
            anchor_label,
            x["ours_steps_per_second"],
            x["anchor_steps_per_second"],
            "steps/s",
            faster="higher",
            goal=f"adapter overhead <= {target:g} µs per agent-step",
            passed=x["pass"],
            note=(
                f"overhead {x['overhead_us_per_agent_step']:.2f} µs per agent-step; the desired velocities are "
                "precomputed, so no controller cost is in either figure (it is measured apart: `controllers`)"
            ),
            detail={"repeats": s["repeats"], **x},
        )
        for x in results
    ]


def main() -> None:
    import jupedsim as jps  # without JuPedSim, the script stops here

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="N = 200 and 2,000 only, fewer steps")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the figures as JSON")
    ap.add_argument("--out", default=None, help="write the printed report as text")
    a = ap.parse_args()
    plan = QUICK_STEPS if a.quick else FULL_STEPS
    load_before = os.getloadavg()
    results, runs = measure(plan, a.repeats)
    verdict = "PASS" if all(x["pass"] for x in results) else "FAIL"
    out = {
        "benchmark": f"JuPedSimEngine (JuPedSim backend, steered every step) vs JuPedSim alone, {SIDE:g}x{SIDE:g} m "
        f"room, collision-free speed model, dt={DT:g} s, radius={RADIUS:g} m, same run, best of {a.repeats}",
        "anchor": "jupedsim Simulation built as JuPedSimAdapter does, one fixed target per agent, sim.iterate()",
        "target_overhead_us_per_agent_step": TARGET_OVERHEAD_US,
        "verdict": verdict,
        "results": results,
        "runs": runs,
        "quick": a.quick,
        "repeats": a.repeats,
        "load_average_before": list(load_before),
        "load_average_after": list(os.getloadavg()),
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}, jupedsim {jps.__version__}",
    }
    lines = [
        f"# {out['benchmark']}",
        f"# machine: {out['machine']}",
        f"# load average before / after: {load_before[0]:.2f} / {out['load_average_after'][0]:.2f}",
        "",
        "| N | steps | anchor steps/s | ours steps/s | ratio ours/anchor (time) | overhead µs/agent-step |",
        "|---|---|---|---|---|---|",
    ]
    for x in results:
        lines.append(
            f"| {x['n']} | {x['steps']} | {x['anchor_steps_per_second']:.1f} | {x['ours_steps_per_second']:.1f} | "
            f"{x['ratio_ours_over_anchor_time']:.2f} | {x['overhead_us_per_agent_step']:.2f} |"
        )
    lines += [
        "",
        "Pieces of crowd.step, µs per agent-step (best of repeats, timed one by one):",
        "",
        "| N | steering_targets | adapter.steer | adapter.positions | sum of the three | adapter.iterate | anchor |",
        "|---|---|---|---|---|---|---|",
    ]
    for x in results:
        p = x["pieces_us_per_agent_step"]
        lines.append(
            f"| {x['n']} | {p['steering_targets']:.3f} | {p['steer']:.3f} | {p['positions']:.3f} | "
            f"{x['pieces_overhead_us_per_agent_step']:.3f} | {p['iterate']:.3f} | {x['anchor_us_per_agent_step']:.3f} |"
        )
    lines += [""]
    for x in results:
        lines.append(
            f"N={x['n']}: overhead {x['overhead_us_per_agent_step']:.2f} µs/agent-step "
            f"(target <= {TARGET_OVERHEAD_US:g}): {'PASS' if x['pass'] else 'FAIL'}; "
            f"dominant piece: {x['dominant_piece']}"
        )
    lines.append(f"verdict: {verdict}")
    report = "\n".join(lines)
    print(report)
    write_files(out, a.json, report, a.out)


if __name__ == "__main__":
    main()
