"""The corridor of the bottleneck scaled by ``L`` (the ``two_scales`` check's limit): who is in it, how fast they walk.

``verification.two_scales.bottleneck(2.0, L)`` with the point masses (the headway door model, the fastest route),
stepped to 90 % out; every ``L`` seconds from ``5 L`` s on, the people in the corridor (``x`` beyond the room's
east wall), their density there (persons/m²) and their mean speed along it over the last ``L`` seconds (m/s); at
the end the flow per metre of door over the run's second half, and where the flow is lost: over every step from
``5 L`` s on, in the metre before the corridor's mouth, the corridor's first metre and the rest of it (each as
wide as the corridor), the people's density, the speed factor ``f`` of (H1) they walk at against the diagram's
``g`` at that density, the density (H1) reads from their headways, the ``x`` component of their route's direction
and of their line of walk (H4), and their walk's ``x`` velocity over ``v₀``.  Run from the repository's root::

    python studies/two_scales_corridor.py --scale 2 --seed 0                    # sigma 0.05: 1.62 persons/(m·s)
    python studies/two_scales_corridor.py --scale 2 --seed 0 --sigma 0.01       # 1.78
    python studies/two_scales_corridor.py --scale 2 --route-radius 2            # routes planned on a 2 m disk

Measured 2026-12-05 (docs page *Verification*, "One crowd at two scales"): at ``L = 2`` and σ = 0.05 m²/s, 2.0
persons/m² walking 0.68 m/s (the diagram: 0.84); at σ = 0.01, 2.1–2.3 persons/m² at 0.74–0.79 m/s.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    from meanfield.simulation.loop import ClosedLoop
    from verification.two_scales import bottleneck

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", type=float, default=2.0, help="L, the room's lengths times L")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--sigma", type=float, default=None, help="crowd.sigma, m²/s (default: the scenario's)")
    p.add_argument("--route-radius", type=float, default=None,
                   help="m: the disk (R2) the agents' routes count the crowd over (default: crowd.congestion_radius)")
    a = p.parse_args()
    L = a.scale
    sc = bottleneck(2.0, L, "point-mass", a.seed)
    if a.sigma is not None:
        sc = sc.with_values({"crowd.sigma": a.sigma})
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    engine, door, guidance = crowd.engine, crowd._door, crowd.guidance
    if a.route_radius is not None:
        guidance.radius = float(a.route_radius)
    x0, area = 10.0 * L, 2.0 * L * 2.0 * L
    zones = (("the metre before the mouth", x0 - 1.0, x0), ("the corridor's first metre", x0, x0 + 1.0),
             ("the rest of the corridor", x0 + 1.0, x0 + 2.0 * L))  # fmt: skip
    lo, hi = 3.0 * L, 5.0 * L  # the corridor's walls, and the mouth's strip in the room
    sums = np.zeros((len(zones), 7))  # people, f, headway's density, route x, walk x, x velocity, (steps)
    chosen: dict[str, np.ndarray] = {}
    choose = door.choose_direction

    def choose_and_keep(positions, e, active, cells):  # (H4) as the model runs it, its choice kept to be read
        s, f, walk = choose(positions, e, active, cells)
        chosen.update(s=s, f=f, walk=walk, e=e.copy())
        return s, f, walk

    door.choose_direction = choose_and_keep
    slow_down = crowd._slow_down

    def slow_down_and_read(velocity, positions, t, dt):
        slow_down(velocity, positions, t, dt)
        if t < 5.0 * L or not chosen:
            return
        x, active = positions, engine.active
        for z, (_, a0, a1) in enumerate(zones):
            m = active & (x[:, 0] >= a0) & (x[:, 0] < a1) & (x[:, 1] > lo) & (x[:, 1] < hi)
            sums[z, 6] += 1
            if not m.any():
                continue
            sums[z, :6] += (m.sum(), chosen["f"][m].sum(), np.minimum(door.density(chosen["s"][m]), 10.0).sum(),
                            chosen["e"][m, 0].sum(), chosen["walk"][m, 0].sum(), velocity[m, 0].sum())  # fmt: skip

    crowd._slow_down = slow_down_and_read
    previous, t_next, rows = engine.positions.copy(), 5.0 * L, []
    print("t (s), in the corridor, persons/m², speed along it (m/s), out")
    while engine.remaining() > 0.1 * engine.n and loop.t < sc.t_final:
        loop.step()
        if loop.t < t_next - 1e-9:
            continue
        x = engine.positions
        inside = engine.active & (x[:, 0] > x0)
        moved = (x - previous)[inside & np.isfinite(previous[:, 0])]
        speed = float(moved[:, 0].mean() / L) if len(moved) else float("nan")
        rows.append((loop.t, int(inside.sum()), inside.sum() / area, speed, engine.n - engine.remaining()))
        print(f"{loop.t:.1f}, {rows[-1][1]}, {rows[-1][2]:.2f}, {speed:.3f}, {rows[-1][4]}", flush=True)
        previous, t_next = x.copy(), t_next + L
    half = len(rows) // 2
    flow = (rows[-1][4] - rows[half][4]) / (rows[-1][0] - rows[half][0]) / (2.0 * L)
    print(f"flow per metre of door over the second half: {flow:.3f} persons/(m·s)")
    v0 = crowd.congestion.free_speed
    print("zone, persons/m², f, g at that density, density read from the headways, route x, walk x, "
          "x velocity / v0, flux (persons/(m·s))")
    for (name, a0, a1), (n, f, rho_s, ex, wx, vx, steps) in zip(zones, sums, strict=True):
        rho = n / steps / ((a1 - a0) * (hi - lo))
        g = float(crowd.congestion.speed_factor(np.array([rho]))[0])
        print(f"{name}, {rho:.2f}, {f / n:.3f}, {g:.3f}, {rho_s / n:.2f}, {ex / n:.3f}, {wx / n:.3f}, "
              f"{vx / n / v0:.3f}, {rho * vx / n:.2f}")


if __name__ == "__main__":
    main()
