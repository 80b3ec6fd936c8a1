"""The corridor of the bottleneck scaled by ``L`` (the ``two_scales`` check's limit): who is in it, how fast they walk.

``verification.two_scales.bottleneck(2.0, L)`` with the point masses (the headway door model, the fastest route),
stepped to 90 % out; every ``L`` seconds from ``5 L`` s on, the people in the corridor (``x`` beyond the room's
east wall), their density there (persons/m²) and their mean speed along it over the last ``L`` seconds (m/s); at
the end the flow per metre of door over the run's second half.  Run from the repository's root::

    python studies/two_scales_corridor.py --scale 2 --seed 0                    # sigma 0.05: 1.62 persons/(m·s)
    python studies/two_scales_corridor.py --scale 2 --seed 0 --sigma 0.01       # 1.78

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
    a = p.parse_args()
    L = a.scale
    sc = bottleneck(2.0, L, "point-mass", a.seed)
    if a.sigma is not None:
        sc = sc.with_values({"crowd.sigma": a.sigma})
    loop = ClosedLoop(sc)
    engine = loop.crowd.engine
    x0, area = 10.0 * L, 2.0 * L * 2.0 * L
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


if __name__ == "__main__":
    main()
