"""The human crowd: Euler–Maruyama for the SDE (paper, eq. (1)) with reflecting walls.

::

    dX_j = ( u_W(X_j) + v_r(X_j, t) + v_a(X_j, t) ) dt + sqrt(2 σ(X_j, t)) dB_j

The drift is computed by the caller (the closed loop knows the robots and the
interaction); this module owns the positions, the noise and the walls.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield._compiled.core import NO_BOX
from meanfield._compiled.philox import ZIG_FI, ZIG_KI, ZIG_WI, noise_key
from meanfield.crowds._point_mass_loops import euler_maruyama, hold_at_capacity, hold_at_doors
from meanfield.errors import ParameterError, SigmaLike, SimulationDiverged, check_sigma
from meanfield.geometry.region import Region

__all__ = ["PointMassEngine"]

_NOBODY = np.empty(0, dtype=bool)  # euler_maruyama's ``standing`` when nobody stands
_ZIGGURAT = (ZIG_KI, ZIG_WI, ZIG_FI)  # the noise's ziggurat tables, as euler_maruyama takes them


class PointMassEngine:
    """Positions of ``N`` humans and their Euler–Maruyama step.

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Initial positions, inside Ω.
    domain : Region
        Ω; the walls reflect.
    sigma : float or callable
        Diffusion ``σ >= 0`` or ``σ(x, y, t)``; the noise is ``sqrt(2σ) dB``.
    rng : numpy.random.Generator
        The run's generator.  The Brownian increments come from a counter-based generator
        (:mod:`meanfield._compiled.philox`) keyed by a child of it (``rng.spawn``, which leaves
        ``rng``'s own stream where it was): increment ``j`` of step ``n`` is a pure function of
        (key, ``n``, ``j``), the same on any number of threads.  ``rng`` itself draws the exits'
        bridge tests.

    Attributes
    ----------
    noise_seed : int
        The key of the Brownian increments: step ``n``'s are
        :func:`meanfield._compiled.philox.standard_normals` ``(noise_seed, n, ...)`` (0 for those standing).
    standing : ndarray of bool, shape (N,), or None
        Who stands still during the next step (set by the crowd before it: those whose
        pre-movement time has not come, :class:`~meanfield.crowds.agent_crowd.Individuals`).  Their
        Brownian increments are drawn as everyone's (one normal draw per human and step, whoever
        waits), then set to 0; no exit takes them and no bridge test is drawn for them (a person
        who does not move does not leave).  None (the default): nobody, every number as without it.
    """

    body_radius = 0.0  # point masses

    def __init__(self, positions: np.ndarray, domain: Region, sigma: SigmaLike, rng: np.random.Generator):
        positions = np.array(positions, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 2 or len(positions) < 1:
            raise ParameterError("crowd.positions", positions.shape, "an array of shape (N, 2), N >= 1")
        if not np.all(np.isfinite(positions)):
            raise ParameterError("crowd.positions", "non-finite values", "finite positions")
        if not domain.contains(positions[:, 0], positions[:, 1], tol=1e-12).all():
            raise ParameterError("crowd.positions", "points outside Ω", "every human inside the domain")
        sigma = check_sigma("crowd.sigma", sigma)
        self.positions = positions
        # exits (meanfield.geometry.exits): who left, when and where; the positions of those who left are NaN
        from meanfield.geometry.exits import exit_segments

        self.exits = exit_segments(domain)
        self.active = np.ones(len(positions), dtype=bool)
        self.exit_time = np.full(len(positions), np.nan)
        self.exit_index = np.full(len(positions), -1, dtype=np.intp)
        self.domain = domain
        self.sigma = sigma
        self.rng = rng
        self.noise_seed = int(rng.spawn(1)[0].integers(0, 2**64, dtype=np.uint64))
        self._key = noise_key(self.noise_seed)
        self._steps = 0  # steps taken: the noise's counter
        # a region whose walls are not all convex follows each step from its start (Plan.reflect)
        self._path_reflection = bool(getattr(domain, "reflects_along_paths", False))
        self._noise = np.empty_like(positions)  # work array, reused every step
        self._amp_key: tuple | None = None
        self._box = NO_BOX if self._path_reflection else getattr(domain, "box_walls", NO_BOX)
        self.standing: np.ndarray | None = None  # who waits (pre-movement): no noise, no exit
        self.noise_factor: np.ndarray | None = None  # each one's share of σ (the headway model's (H5); None: all)
        self._open: np.ndarray | None = None  # the exits still open, by index (None: all; exits_closed)
        self._is_open = np.ones(len(self.exits), dtype=bool)  # the same, one flag per exit
        self._capacity: np.ndarray | None = None  # persons/s each exit passes at most (None: any; cap_exits)
        self._credit = np.zeros(0)
        self._waiting = np.empty(0, dtype=np.intp)  # who waits in a doorway (sorted), and at which exit
        self._waiting_at = np.empty(0, dtype=np.intp)
        from meanfield.geometry.doors import door_segments

        self.doors = door_segments(domain)  # the plan's inner doors (meanfield.geometry.doors)
        self._door_capacity: np.ndarray | None = None  # persons/s each door passes at most (None: any; cap_doors)

    def cap_exits(self, capacity: np.ndarray) -> None:
        """From now on exit ``k`` passes at most ``capacity[k]`` persons/s, and at most one person more over any
        time (docs page *Congestion*, "The exits' capacity").

        Each exit is a door with a queue, as a server of fixed rate is: its credit grows by ``capacity[k] dt`` a
        step and each human who leaves through it spends one.  Those whose step reached it with no whole credit
        left wait in its doorway, where they stood at the step's start, and are the first it serves (the nearest
        its segment first); while someone waits, the credit is kept whole.  A door nobody waits at keeps at most
        one person's credit: after a pause it passes one person at once, never a burst.  Over any ``τ`` it passes
        at most ``1 + capacity[k] τ`` people, and, while someone waits, ``capacity[k] τ`` within one person: the
        density's exit face, ``min(demand, q_max b)`` at every instant, up to one person.

        Parameters
        ----------
        capacity : ndarray, shape (E,)
            Persons/s, one per exit, each > 0.
        """
        capacity = np.asarray(capacity, float)
        if capacity.shape != (len(self.exits),) or not np.all(capacity > 0) or not np.all(np.isfinite(capacity)):
            raise ParameterError(
                "exit capacity", capacity, f"one finite capacity > 0 per exit, shape ({len(self.exits)},)"
            )
        self._capacity = capacity
        self._credit = np.ones(len(capacity))  # the first to come passes at once
        self._waiting = np.empty(0, dtype=np.intp)
        self._waiting_at = np.empty(0, dtype=np.intp)

    def cap_doors(self, capacity: np.ndarray) -> None:
        """From now on inner door ``k`` (:attr:`doors`) passes at most ``capacity[k]`` persons/s, net, and at most
        one person more over any time (docs page *Congestion*, "The doors' capacity").

        Each door is a queue as each exit is (:meth:`cap_exits`), served in both ways: its credit grows by
        ``capacity[k] dt`` a step and each step through it spends one; a step that would cross it with no whole
        credit left is not taken (the human stays where the step started) and, if the next step crosses it
        again, is served first (the nearest its segment first).  A step back through the door one last passed,
        the other way, is free and gives its credit back (:func:`~meanfield.crowds._point_mass_loops.hold_at_doors`).

        Parameters
        ----------
        capacity : ndarray, shape (D,)
            Persons/s, one per door, each > 0.
        """
        capacity = np.asarray(capacity, float)
        if capacity.shape != (len(self.doors),) or not np.all(capacity > 0) or not np.all(np.isfinite(capacity)):
            raise ParameterError(
                "door capacity", capacity, f"one finite capacity > 0 per door, shape ({len(self.doors)},)"
            )
        n = len(self.positions)
        self._door_capacity = capacity
        self._door_credit = np.ones(len(capacity))  # the first to come passes at once
        self._door_waiting = np.full(n, -1, dtype=np.intp)  # the door each waits at (-1: none)
        self._last_door = np.full(n, -1, dtype=np.intp)  # the door each last passed, and the way (±1)
        self._last_door_sign = np.zeros(n, dtype=np.int8)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on nobody leaves through the exits ``k`` with ``open_exits[k]`` false: they are walls."""
        open_exits = np.asarray(open_exits, dtype=bool)
        if open_exits.shape != (len(self.exits),):
            raise ParameterError("open_exits", open_exits.shape, f"one flag per exit, shape ({len(self.exits)},)")
        self._open = None if open_exits.all() else np.flatnonzero(open_exits)
        self._is_open = open_exits.copy()

    def walls_changed(self, change: Any) -> None:
        """Ω is ``change.region`` from now on (a ``block`` event): its walls reflect, and the humans standing
        in the blocked region step out of it to the nearest point a hair (10⁻⁴ of Ω's diameter) inside Ω."""
        region = change.region
        self.domain = region
        self._path_reflection = bool(getattr(region, "reflects_along_paths", False))
        self._box = NO_BOX if self._path_reflection else getattr(region, "box_walls", NO_BOX)
        here = np.flatnonzero(self.active)
        x = self.positions[here]
        if not region.contains(x[:, 0], x[:, 1]).all():
            try:
                inside = region.robot_region(1e-4 * region.diameter)
            except ParameterError:  # a passage narrower than the hair: onto the wall itself
                inside = region
            inside.project(x)
            self.positions[here] = x

    @property
    def n(self) -> int:
        """Number of humans N."""
        return len(self.positions)

    def step(self, drift: np.ndarray, t: float, dt: float) -> None:
        """One Euler–Maruyama step of eq. (1) with drift (N, 2), then reflect at the walls.

        Raises :class:`~meanfield.errors.SimulationDiverged`, the positions unchanged, if the drift is not finite.
        """
        x = self.positions
        if self._noise.shape != x.shape:  # positions replaced by an array of another size
            self._noise = np.empty_like(x)
        # those waiting do not move: no noise (their drift is 0)
        standing = _NOBODY if self.standing is None else self.standing
        if callable(self.sigma):
            s = np.asarray(self.sigma(x[:, 0], x[:, 1], t), float)
            if len(self.exits):  # σ at those who left (NaN positions) is no one's
                s = np.where(self.active, s, 0.0)
            if np.any(s < 0) or not np.all(np.isfinite(s)):
                raise ParameterError("crowd.sigma", "negative or non-finite σ(x, t)", "σ(x, t) >= 0")
            amp = np.sqrt(2.0 * s * dt)[:, None]
        else:
            amp = self._constant_amplitude(dt)
        if self.noise_factor is not None:  # (H5): σ φ_j (docs page Congestion, "The headway door model")
            amp = amp * np.sqrt(self.noise_factor)[:, None]
        previous = x.copy() if self._path_reflection or len(self.exits) or self._door_capacity is not None else None
        # a box without exits folds its walls into the same pass (meanfield.crowds._field_loops)
        folded = self._box if previous is None else NO_BOX
        step = np.uint64(self._steps)
        if not euler_maruyama(x, drift, self._noise, dt, amp, folded, standing, *self._key, step, *_ZIGGURAT):
            msg = f"non-finite human drift at t = {t:.4g}; the crowd is kept at the last good step"
            raise SimulationDiverged(msg, -1)
        self._steps += 1
        if not len(self.exits):
            if previous is not None:
                self.domain.reflect(x, previous)
            elif not folded.shape[0]:
                self.domain.reflect(x)
            if self._door_capacity is not None:
                moved = self.active if self.standing is None else self.active & ~self.standing
                self._hold_at_doors(np.flatnonzero(moved), previous, dt)
            return
        self._leave_and_reflect(previous, t, dt)

    def _constant_amplitude(self, dt: float) -> np.ndarray:
        """``sqrt(2 σ dt)``, the (1, 1) array :func:`~meanfield.crowds._point_mass_loops.euler_maruyama` takes,
        kept per (σ, dt)."""
        key = (self.sigma, dt)
        if self._amp_key != key:
            self._amp_key, self._amp = key, np.full((1, 1), math.sqrt(2.0 * self.sigma * dt))
        return self._amp

    def _leave_and_reflect(self, previous: np.ndarray, t: float, dt: float) -> None:
        """The humans whose step reached an exit leave (position NaN); the others reflect at the walls."""
        from meanfield.geometry.exits import leaving

        x = self.positions
        idx = np.flatnonzero(self.active if self.standing is None else self.active & ~self.standing)
        sigma = 0.0 if callable(self.sigma) else self.sigma  # a σ(x, t): crossings only, no bridge test
        if self._open is None:
            gone = leaving(previous[idx], x[idx], self.exits, sigma, dt, self.rng)
        elif len(self._open):  # some exits closed: only the open ones take people (their indices mapped back)
            gone = leaving(previous[idx], x[idx], self.exits[self._open], sigma, dt, self.rng)
            gone = np.where(gone >= 0, self._open[np.maximum(gone, 0)], -1)
        else:  # every exit closed: the boundary is all wall
            gone = np.full(len(idx), -1, dtype=np.intp)
        if self._capacity is not None:
            self._hold_at_capacity(gone, idx, previous, dt)
        out = idx[gone >= 0]
        self.active[out] = False
        self.exit_time[out] = t + dt
        self.exit_index[out] = gone[gone >= 0]
        x[out] = np.nan
        stay = idx[gone < 0]
        moved = x[stay]
        if self._path_reflection:
            self.domain.reflect(moved, previous[stay])
        else:
            self.domain.reflect(moved)
        x[stay] = moved
        if self._door_capacity is not None:
            self._hold_at_doors(stay, previous, dt)

    def _hold_at_capacity(self, gone: np.ndarray, idx: np.ndarray, previous: np.ndarray, dt: float) -> None:
        """The exits' queues (:meth:`cap_exits`; :func:`~meanfield.crowds._point_mass_loops.hold_at_capacity`), in
        place on ``gone`` (the exit each human of ``idx`` reached, -1: none) and on the positions: those an exit
        cannot take this step get -1, their step's start, and a place in its doorway."""
        self._credit, self._waiting, self._waiting_at = hold_at_capacity(
            gone, idx, previous, self.positions, self.exits, self._capacity, self._credit, self._waiting,
            self._waiting_at, self._is_open, float(dt),
        )  # fmt: skip

    def _hold_at_doors(self, idx: np.ndarray, previous: np.ndarray, dt: float) -> None:
        """The inner doors' queues (:meth:`cap_doors`) for the humans ``idx`` who stepped and stayed (sorted),
        after the walls: those a door cannot take this step go back to their step's start."""
        self._door_credit = hold_at_doors(
            idx, previous, self.positions, self.doors, self._door_capacity, self._door_credit, self._door_waiting,
            self._last_door, self._last_door_sign, float(dt),
        )  # fmt: skip

    def remaining(self) -> int:
        """How many humans have not left."""
        return int(np.count_nonzero(self.active))

    def summary(self) -> dict[str, Any]:
        """With exits: how many left through each exit, the last exit time (else nothing)."""
        if not len(self.exits):
            return {}
        out = ~self.active
        return {
            "evacuated_per_exit": np.bincount(self.exit_index[out], minlength=len(self.exits)).tolist(),
            "last_exit_time": float(np.nanmax(self.exit_time)) if out.any() else None,
            "everyone_out": bool(out.all()),
        }
