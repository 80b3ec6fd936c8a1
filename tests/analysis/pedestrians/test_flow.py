"""PedPy's speed and flow of a run (analysis.pedestrians.flow; issue 16, item 10), against walkers
whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.optional import load

pytestmark = pytest.mark.requires("pedpy")
pedpy = load("pedpy")
pd = pytest.importorskip("pandas")
shapely = pytest.importorskip("shapely")

from analysis.pedestrians.flow import entry_line, speed_and_flow  # noqa: E402


def test_the_entry_line_faces_the_room_at_the_target_radius():
    room = shapely.box(0, 0, 10, 10)
    line = entry_line(room, (9.0, 9.0), 2.0)
    mid = np.mean(np.asarray(line.coords), axis=0)
    assert math.dist(mid, (9.0, 9.0)) == pytest.approx(2.0)  # at the radius, on the room's side
    d = np.subtract(line.coords[1], line.coords[0])
    assert abs(d[0] - (-d[1])) < 1e-9 or abs(d[0] + d[1]) < 1e-9  # perpendicular to the diagonal
    assert room.covers(line)


def test_walkers_at_a_known_speed_cross_the_entry_line_once_each():
    v, fps, n, frames = 1.5, 10.0, 5, 70  # 6.9 s: every walker crosses, none leaves the room
    direction = np.array([1.0, 1.0]) / math.sqrt(2.0)
    rows = []
    for i in range(n):
        start = np.array([1.0 + 0.5 * i, 1.0])  # parallel lanes, all heading to the corner
        for f in range(frames):
            x, y = start + v * (f / fps) * direction
            rows.append((i, f, x, y))
    data = pd.DataFrame(rows, columns=["id", "frame", "x", "y"])
    traj = pedpy.TrajectoryData(data=data, frame_rate=fps)
    room = pedpy.WalkableArea(shapely.box(0, 0, 12, 12))
    out = speed_and_flow(traj, room, (9.0, 9.0), 2.0)  # entry line x + y = 15.17
    assert out["speed_median"] == pytest.approx(v, rel=1e-9) and out["speed_max"] == pytest.approx(v, rel=1e-9)
    assert np.allclose(out["mean_speed"], v)
    assert out["crossings"] == n and out["n_t"][-1] == n
    assert out["flow_mean"] is not None and out["flow_mean"] > 0
