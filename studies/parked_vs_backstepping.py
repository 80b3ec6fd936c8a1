"""The paper's law against robots parked on a lattice with their signs at the target (docs/examples).

Run from the repository's root:  python studies/parked_vs_backstepping.py [--seeds 10]

Prints, per controller, the median and the worst seed of the final fraction in the target
region, the time to 90 % and the final density error ‖ρ̂ − ρ_*‖ on the built-in ``paper``
scenario (t_final = 40).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys

import numpy as np

from meanfield import paper_scenario, run


def _register_parked() -> None:
    spec = importlib.util.spec_from_file_location("parked_robots", "docs/examples/parked_robots.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["parked_robots"] = module
    spec.loader.exec_module(module)  # registers controller.kind = "parked"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    seeds = range(ap.parse_args().seeds)
    _register_parked()
    for kind in ("backstepping", "parked"):
        scenarios = [paper_scenario(seed=s).with_values({"controller.kind": kind}) for s in seeds]
        rows = [run(sc, progress=False).summary for sc in scenarios]
        frac = np.array([r["fraction_in_target"] for r in rows])
        t90 = np.array([np.inf if r["time_to_90"] is None else r["time_to_90"] for r in rows])
        err = np.array([r["l2_error_final"] for r in rows])
        print(
            f"{kind:>12}: in target median {np.median(frac):.3f} worst {frac.min():.3f}; "
            f"time to 90 % median {np.median(t90):.3g} worst {t90.max():.3g}; "
            f"||rho - rho*|| median {np.median(err):.3f} worst {err.max():.3f}"
        )


if __name__ == "__main__":
    main()
