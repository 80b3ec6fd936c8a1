"""People in groups: each group placed in its own region of the plan, and walking to its own exit.

An evacuation engineer places people room by room and may assign them to exits (RiMEA's
guideline, test 10: the people of some rooms use the main exit, the others a secondary one).
``crowd.initial = "groups"`` with one ``[[crowd.groups]]`` table per group::

    [[crowd.groups]]
    region = "POLYGON ((0 0, 3 0, 3 5, 0 5, 0 0))"   # where its people stand (inside the plan)
    n = 2                                            # how many
    exit = 0                                         # optional: the index into domain.exits they walk to

* each group's people are drawn uniformly in its region (the part inside the plan), group
  after group, from the run's generator (:func:`group_positions`); ``crowd.n`` is their sum;
* the informed crowd (``crowd.guidance = "geodesic"``) walks each person's route to its
  group's exit (:class:`~meanfield.crowds.guidance.GeodesicGuidance`), or to the nearest
  exit for a group without one; an assigned exit that closes (``[[events]]``) sends its
  people to the nearest open exit.

Refused, naming the field: a missing or unknown key, ``n < 1``, a region that is not a
polygon or lies outside the plan, an exit the plan does not have, groups whose sizes do not
add up to ``crowd.n``, groups without ``initial = "groups"`` or the reverse, a crowd that
does not place people in groups (it declares no ``places_groups``: the point masses, JuPedSim's bodies and the
density do), and a group's ``exit`` with a crowd that cannot keep one per group (it declares no ``group_exits``: the
point masses and JuPedSim's bodies do).
The density starts as the point masses are drawn, each group uniform in its region
(:func:`meanfield.crowds.density_crowd.initial_density`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.errors import ParameterError, integer

__all__ = ["GROUP_KEYS", "crowd_groups", "group_positions", "assigned_exits", "group_region"]

GROUP_KEYS = ("region", "n", "exit")
"""The keys of a ``[[crowd.groups]]`` table (``exit`` optional)."""


def crowd_groups(value: Any, initial: str, n: int) -> list[dict[str, Any]]:
    """``crowd.groups`` checked against ``crowd.initial`` and ``crowd.n`` (module docstring): a list of tables."""
    groups = [] if value is None else value
    if not isinstance(groups, (list, tuple)):
        allowed = 'an array of tables [[crowd.groups]] (with crowd.initial = "groups")'
        raise ParameterError("crowd.groups", groups, allowed)
    if initial != "groups":
        if groups:
            raise ParameterError("crowd.groups", f"{len(groups)} group(s)", 'none unless crowd.initial = "groups"')
        return []
    if not isinstance(groups, (list, tuple)) or not groups:
        raise ParameterError("crowd.groups", groups, 'one [[crowd.groups]] table or more with crowd.initial = "groups"')
    out = []
    for i, g in enumerate(groups):
        name = f"crowd.groups[{i}]"
        if not isinstance(g, dict):
            raise ParameterError(name, g, "a table with region, n and optionally exit")
        unknown = sorted(set(g) - set(GROUP_KEYS))
        if unknown:
            raise ParameterError(f"{name}.{unknown[0]}", g[unknown[0]], f"keys among {list(GROUP_KEYS)}")
        for key in ("region", "n"):
            if key not in g:
                raise ParameterError(f"{name}.{key}", None, "a value (region: a WKT polygon; n: an integer >= 1)")
        g = {**g, "n": integer(f"{name}.n", g["n"], 1)}  # 100.0 is 100, as for crowd.n; 100.5 is refused
        if g.get("exit") is not None:
            try:
                g["exit"] = integer(f"{name}.exit", g["exit"], 0)
            except ParameterError:
                allowed = "an index into domain.exits (an integer >= 0)"
                raise ParameterError(f"{name}.exit", g["exit"], allowed) from None
        group_region(g["region"], f"{name}.region")
        out.append({k: g[k] for k in GROUP_KEYS if k in g})
    total = sum(g["n"] for g in out)
    if total != n:
        raise ParameterError("crowd.n", n, f"the groups' sizes added up, {total}")
    return out


def group_region(wkt: Any, name: str = "crowd.groups[i].region") -> Any:
    """A group's region as a shapely polygon or multipolygon (refused, naming ``name``, unless valid, of positive area;
    :func:`~meanfield.geometry.region.wkt_polygon`)."""
    from meanfield.geometry.region import wkt_polygon

    return wkt_polygon(wkt, name, pieces=True)


def group_positions(groups: list[dict[str, Any]], domain: Any, rng: np.random.Generator) -> np.ndarray:
    """Each group's people uniform in its region ∩ Ω, group after group (rejection from the region's box)."""
    import shapely

    out = []
    for i, g in enumerate(groups):
        poly = group_region(g["region"], f"crowd.groups[{i}].region")
        x0, y0, x1, y1 = poly.bounds
        kept = np.empty((0, 2))
        for _ in range(1000):
            need = g["n"] - len(kept)
            if need <= 0:
                break
            p = rng.uniform((x0, y0), (x1, y1), size=(4 * need + 8, 2))
            ok = shapely.contains_xy(poly, p[:, 0], p[:, 1]) & np.asarray(domain.contains(p[:, 0], p[:, 1]), bool)
            kept = np.vstack([kept, p[ok]])
        if len(kept) < g["n"]:
            raise ParameterError(f"crowd.groups[{i}].region", g["region"], "a region with room inside the plan")
        out.append(kept[: g["n"]])
    return np.vstack(out)


def assigned_exits(groups: list[dict[str, Any]]) -> np.ndarray:
    """Each person's assigned exit, in the order of :func:`group_positions` (-1: the nearest)."""
    return np.concatenate([np.full(g["n"], g.get("exit", -1), dtype=np.intp) for g in groups])
