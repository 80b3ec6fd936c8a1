"""The closed loop: one step, written once, for any crowd and any controller.

One step of :class:`ClosedLoop` (``dt``; docs page *Architecture*):

0. the scenario's events due now happen (``[[events]]``: an exit closes, and every part that
   declares ``exits_closed`` is told; or a region becomes wall, and every part that declares
   ``walls_changed`` is told; docs page *Buildings*, "Events");
1. observe: the crowd's density on the grid (a KDE of agents, or the PDE's density) and
   the robots' kernels at their states (:class:`~meanfield.interfaces.Observation`);
2. act: the controller's robot inputs ``(u_i, ω_i)`` (eq. (8) for the paper's law);
3. the crowd advances under the robots' signs (eq. (1) for agents, eq. (4) for the density);
4. the robots advance, their inputs saturated at the speed limits (eq. (2)), kept in
   their region;
5. the observers see the step (recording, time to 90 %, input statistics, ...).

The loop holds no recording and computes no summary: observers do
(:mod:`meanfield.simulation.observers`, :mod:`meanfield.simulation.summary`), as py-pde's trackers watch its
solvers.  :meth:`ClosedLoop.run` attaches the standard observers and returns a result;
:func:`run` assembles a scenario first.
"""

from __future__ import annotations

import copy
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from meanfield._compiled.threads import limited_blas
from meanfield._compiled.warmup import compile_in_parallel, parallel_compile_possible
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.geometry.exits import exit_segments, tell_exits_closed
from meanfield.interfaces import Observation
from meanfield.scenarios.scenario import Scenario, load_scenario
from meanfield.signs.robots import NavigationField, limited_inputs
from meanfield.simulation.assembly import Parts, assemble
from meanfield.simulation.evacuation_measures import EvacuationTracker
from meanfield.simulation.observers import InputStatistics, Observer, Recorder, StepRecord, TargetTracker
from meanfield.simulation.preflight import stability_warnings
from meanfield.simulation.result import SimulationResult
from meanfield.simulation.stragglers import StragglerTracker
from meanfield.simulation.summary import run_id, run_summary

# Observer, StepRecord: from meanfield.simulation.observers
__all__ = ["ClosedLoop", "Observer", "StepRecord", "run", "signals_deferred"]


class ClosedLoop:
    """Steps the parts of a closed loop: crowd, robots and controller.

    Parameters
    ----------
    parts : Parts or Scenario
        The parts from :func:`meanfield.simulation.assembly.assemble`; a scenario is assembled here
        (with ``overrides``).
    observers : sequence of Observer
        Called at the start and after every step.
    **overrides
        For a scenario: passed to :func:`~meanfield.simulation.assembly.assemble` (``sigma``,
        ``disturbance``, ``beta_gamma``, ``kernel``, ``crowd``, ``controller``).

    Examples
    --------
    >>> from meanfield import ClosedLoop, paper_scenario
    >>> loop = ClosedLoop(paper_scenario(seed=1).replace(t_final=0.1))
    >>> result = loop.run(progress=False)
    >>> result.summary["status"], result.summary["steps"]
    ('completed', 10)
    """

    def __init__(self, parts: Any, *, observers: Any = (), **overrides: Any):
        if isinstance(parts, Scenario):
            parts = assemble(parts, **overrides)
        elif overrides:
            raise ParameterError("overrides", sorted(overrides), "none when the loop is given assembled parts")
        if not isinstance(parts, Parts):
            raise ParameterError("scenario", type(parts).__name__, "a Scenario (or the Parts of one)")
        self.parts = parts
        self.scenario = parts.scenario
        self.crowd = parts.crowd
        self.robots = parts.robots
        self.controller = parts.controller
        self.grid = parts.grid
        self.dt = parts.scenario.dt
        self.observers = list(observers)
        self.t = 0.0
        self.step_index = 0
        controller_half, plant_half = self._first_step_halves()
        halves = [h for h in (controller_half, plant_half) if h is not None]  # the law compiles longest: first
        # (only on a cold cache: meanfield._compiled.warmup) the children are awaited just before the first act,
        # so that what comes between (the observers' start, say) compiles here beside them
        with compile_in_parallel(halves, wait=False) as self._compilers:
            self.density: np.ndarray = self.crowd.density()
            r = self.robots  # the step's input limits, a pure function, compile here: less for the plant's child
            zeros_u, zeros_w = np.zeros((len(r.positions), 2)), np.zeros(len(r.positions))
            limited_inputs(zeros_u, zeros_w, r.u_max, r.omega_max)
            if plant_half is not None:  # and the robots' step, on a copy of them: one loop less for the plant's child
                copy.deepcopy(r).advance(zeros_u, zeros_w, self.dt, self.parts.robot_region)
        # a build that compiled nothing (the saturation already compiled, and a density that compiles nothing, as
        # the Fokker-Planck crowd's) forked nothing: then the plant's half compiles in a child beside the first
        # step's act, which compiles the law here (_act)
        self._plant_beside_first_act = [plant_half] if plant_half and parallel_compile_possible() else None
        self.last: StepRecord | None = None  # the latest step, as observers saw it
        self._started = False
        # the scenario's [[events]], in time order: each closes an exit before the first step that starts at its time
        self._events = list(parts.scenario.events)
        n_exits = len(exit_segments(parts.region)) if self._events else 0
        self.open_exits = np.ones(n_exits, dtype=bool)
        self.events_done: list[dict[str, Any]] = []

    def _first_step_halves(self) -> tuple[Callable[[], Any] | None, Callable[[], Any] | None]:
        """The first step in two halves, the controller's and the plant's, for
        :func:`~meanfield._compiled.warmup.compile_in_parallel` (None: a half that may not run in a child).

        Each runs in a forked child, on the child's copy of the loop, only to compile (and
        cache) the loops it calls: the controller acts on a stand-in density, the target ``ρ_*``
        (which loops compile depends on the arrays' types, and on the branches their values take:
        on zeros the guide skipped its exits' price iteration, which the parent then compiled
        after the children); the crowd takes one
        step under the robots as they are, and the robots one with zero inputs (their
        saturation, a pure function, and their step, on a copy of them, compile in this process
        beside the first density: the child then reads them from the cache, and ends sooner).
        Only the toolkit's own parts are called in a child: a plug-in's part might act on the
        world (a real robot taking its command), so its loops compile here, in this process,
        when it first runs.
        """

        def controller_half() -> None:
            self.controller.act(Observation(np.array(self.parts.target, float), self._field(), self.t, self.dt))

        def plant_half() -> None:
            self.crowd.advance(self.robots, self.t, self.dt)
            r = self.robots
            r.advance(np.zeros((len(r.positions), 2)), np.zeros(len(r.positions)), self.dt, self.parts.robot_region)

        plant = _toolkit_part(self.crowd) and _toolkit_part(self.robots)
        return (controller_half if _toolkit_part(self.controller) else None), (plant_half if plant else None)

    # the parts, by name (read-only conveniences)
    @property
    def kernel(self):
        return self.parts.kernel

    @property
    def target(self) -> np.ndarray:
        return self.parts.target

    @property
    def domain(self):
        return self.parts.region

    @property
    def robot_region(self):
        return self.parts.robot_region

    def attach(self, observer: Any) -> None:
        """Add an observer (it sees the current state at once if the loop has started)."""
        self.observers.append(observer)
        if self._started:
            observer.start(self)

    def observe(self) -> Observation:
        """What the robots know now: the density on the grid, their kernels, the time."""
        return Observation(self.density, self._field(), self.t, self.dt)

    def _field(self) -> NavigationField:
        """The robots' kernels on the grid at their current states."""
        r = self.robots
        return NavigationField(self.parts.kernel, self.grid, r.positions, r.headings, self.parts.sight)

    def _act(self, observation: Observation) -> Any:
        """The first step's act: once the children compiling the step's halves are done (they cached the loops it
        calls), or with the plant's half compiling in a child meanwhile if nothing was forked at the build."""
        compilers, self._compilers = self._compilers, None  # (None: the first act is done)
        compilers.wait()
        tasks, self._plant_beside_first_act = self._plant_beside_first_act, None
        with compile_in_parallel(tasks or ()):
            return self.controller.act(observation)

    def start(self) -> None:
        """Show the initial state to the observers (once; :meth:`step` calls it if needed)."""
        if not self._started:
            self._started = True
            for obs in self.observers:
                obs.start(self)

    def step(self) -> StepRecord:
        """Advance the closed loop by one ``dt``; raise :class:`SimulationDiverged` on NaN/inf.

        The state is only changed when the robot inputs and the crowd's velocities are
        finite, so after the exception the loop still holds the last good state.
        """
        self.start()
        k, dt = self.step_index, self.dt
        while self._events and self._events[0].time <= self.t + 1e-9 * dt:
            event = self._events.pop(0)
            getattr(self, f"_{event.action}")(event)  # _close_exit or _block
        observation = self.observe()
        command = self.controller.act(observation) if self._compilers is None else self._act(observation)
        u, w, report = limited_inputs(command.u, command.omega, self.robots.u_max, self.robots.omega_max)
        if not report[4]:
            raise SimulationDiverged(
                f"non-finite robot inputs at t = {self.t:.4g} (step {k}); the state is kept at the last good step", k
            )
        if command.shows is not None:  # the exits the signs name from now on
            self.robots.shows = np.asarray(command.shows, dtype=np.intp).copy()
        try:
            self.crowd.advance(self.robots, self.t, dt)
        except SimulationDiverged as exc:
            raise SimulationDiverged(f"{exc} (step {k})", k) from None
        self.robots.advance(u, w, dt, self.parts.robot_region)
        self.step_index = k + 1
        self.t = self.step_index * dt
        self.density = self.crowd.density()
        if not _all_finite(self.density):
            raise SimulationDiverged(f"non-finite density at t = {self.t:.4g}", self.step_index)
        record = self.last = StepRecord(k, observation, command, u, w, self.robots, report)
        for obs in self.observers:
            obs.step(self, record)
        return record

    def _close_exit(self, event: Any) -> None:
        """An event: exit ``event.close_exit`` closes now; every part that has ``exits_closed`` is told
        (the crowd stops taking people through it and re-plans; a controller planning to the exits learns it)."""
        self.open_exits[event.close_exit] = False
        tell_exits_closed((self.crowd, self.controller), self.open_exits)
        self.events_done.append(
            {"time": event.time, "at": self.t, "close_exit": event.close_exit, "exits_open": int(self.open_exits.sum())}
        )

    def _block(self, event: Any) -> None:
        """An event: the region ``event.block`` becomes wall now (:mod:`meanfield.geometry.blocking`).

        Ω, its grid (the same cells, cut again), sight lines, robot region and ``ρ_*`` are built for
        ``Ω ∖ B``; every part that has ``walls_changed`` is told (the crowd's people in ``B`` step out of it
        and its routes are planned again; the controller plans again); the density is estimated again on
        the new grid, so the robots' next observation is of the new Ω.
        """
        from meanfield.geometry.blocking import WallsChange, blocked_region, tell_walls_changed
        from meanfield.geometry.grid import Grid
        from meanfield.geometry.region import wkt_polygon
        from meanfield.geometry.sight import SightLines
        from meanfield.geometry.target import gaussian_target, target_region_radius

        p, sc = self.parts, self.scenario
        polygon = wkt_polygon(event.block, f"{event.name}.block")
        region = blocked_region(p.region, polygon, f"{event.name}.block")
        grid = Grid(region, p.grid.cells, p.grid.cut_cells)
        target = gaussian_target(grid, sc.target.center, sc.target.std)
        change = WallsChange(region, grid, SightLines(region), region.robot_region(sc.robots.margin), target, polygon)
        p.region, p.grid, p.sight, p.robot_region, p.target = region, grid, change.sight, change.robot_region, target
        p.target_radius = target_region_radius(region, sc.target.center, sc.target.std)
        self.grid = grid
        tell_walls_changed((self.crowd, self.controller), change)
        change.robot_region.project(self.robots.positions)  # (in place) a robot in B steps out of it
        self.density = self.crowd.density()
        self.events_done.append({"time": event.time, "at": self.t, "block": event.block})

    @property
    def no_exit_left(self) -> bool:
        """True once events have closed every exit (nobody can leave any more)."""
        return bool(self.events_done) and not self.open_exits.any()

    def run(self, progress: bool = True, callback: Callable[[ClosedLoop], None] | None = None) -> SimulationResult:
        """Run to ``t_final`` with the standard observers, recording every ``record_every`` steps.

        :class:`~meanfield.simulation.observers.TargetTracker`, :class:`~meanfield.simulation.observers.InputStatistics`
        and :class:`~meanfield.simulation.observers.Recorder` watch the run;
        :func:`~meanfield.simulation.summary.run_summary` reads them at the end.

        Parameters
        ----------
        progress : bool
            Show a tqdm progress bar.
        callback : callable, optional
            Called as ``callback(loop)`` after every step.

        Returns
        -------
        SimulationResult
            With ``summary["status"]`` ``"completed"``, ``"diverged"`` (the message in
            ``summary["message"]``; frames up to the last good state) or ``"interrupted"``
            (KeyboardInterrupt; frames so far).
        """
        from tqdm.auto import tqdm

        with limited_blas():  # small products on one BLAS thread (MEANFIELD_BLAS_THREADS to change)
            return self._run(progress, callback, tqdm)

    def _run(self, progress: bool, callback: Callable[[ClosedLoop], None] | None, tqdm: Any) -> SimulationResult:
        loop = self
        sc = loop.scenario
        target, inputs = TargetTracker(0.9), InputStatistics()
        recorder = Recorder(target)
        evacuation, stragglers = EvacuationTracker(), StragglerTracker()
        for obs in (target, inputs, recorder, evacuation, stragglers):
            loop.attach(obs)
        loop.start()
        p = loop.parts
        rho_err0 = loop.grid.norm(loop.density - p.target)
        status, message = "completed", ""
        first = loop.step_index
        n_steps = sc.steps - first
        start = time.perf_counter()
        bar = None  # shown once the first step is done: it loads (or compiles) the compiled loops
        try:
            remaining = loop.crowd.remaining_fraction if recorder.exits else None  # only with exits
            # everyone is out when less than half a person is left: for agents none (a count), for the
            # density 1 - 0.5/N of its mass out, which never reaches exactly 0 (as the evacuation measures)
            half_person = 0.5 / (loop.crowd.n if loop.crowd.n is not None else sc.crowd.n)
            with _stop_between_steps() as stop_requested:
                for _ in range(n_steps):
                    if stop_requested():
                        raise KeyboardInterrupt
                    loop.step()
                    if bar is None:
                        desc = f"meanfield run {sc.name}"
                        bar = tqdm(total=n_steps, disable=not progress, desc=desc, unit="step", mininterval=0.5)
                    if recorder.last_recorded_step == loop.step_index:
                        bar.update(loop.step_index - first - bar.n)
                    if callback is not None:
                        callback(loop)
                    if remaining is not None and remaining() < half_person:
                        message = f"everyone left through the exits at t = {loop.t:.4g}"
                        break
                    if loop.no_exit_left:  # the events closed every exit: nobody can leave any more
                        at = loop.events_done[-1]["at"]
                        message = f"no exit left: the last open exit closed at t = {at:.4g}"
                        break
        except SimulationDiverged as exc:
            status, message = "diverged", str(exc)
        except KeyboardInterrupt:
            status, message = "interrupted", f"interrupted at t = {loop.t:.4g}"
        except SystemError as exc:  # a second Ctrl-C inside a compiled call surfaces as this
            if not isinstance(exc.__cause__, KeyboardInterrupt):
                raise
            status, message = "interrupted", f"interrupted at t = {loop.t:.4g}"
        finally:
            if bar is not None:
                bar.close()
            for obs in (target, inputs, recorder, evacuation, stragglers):
                loop.observers.remove(obs)
        wall = time.perf_counter() - start
        recorder.finish()
        timeseries = recorder.timeseries()
        summary = run_summary(
            loop,
            target,
            inputs,
            recorder,
            timeseries,
            status=status,
            message=message,
            rho_err0=rho_err0,
            wall=wall,
            steps_run=loop.step_index - first,
            measures={**evacuation.summary(), **stragglers.summary(loop), **_events_summary(loop)},
        )
        rid = run_id(loop, status)
        summary = {"run_id": rid, **summary, "warnings": stability_warnings(sc, loop.grid, summary)}
        timeseries.attrs.update(run_id=rid, status=status, message=message)
        return SimulationResult(sc, timeseries, summary, p.kernel)


def _events_summary(loop: ClosedLoop) -> dict[str, Any]:
    """``events`` (what happened, when, and how many exits were left open) and ``no_exit_left``; nothing
    without events."""
    if not loop.scenario.events:
        return {}
    return {"events": list(loop.events_done), "no_exit_left": loop.no_exit_left}


def _all_finite(a: np.ndarray) -> bool:
    """Whether every entry of ``a`` is finite (``np.isfinite(a).all()``; counting costs 60 % of ``all``'s call)."""
    return np.count_nonzero(np.isfinite(a)) == a.size


def _toolkit_part(part: Any) -> bool:
    """Whether ``part`` is one of the toolkit's own (``meanfield`` or ``analysis``): calling it has no effect
    outside this process."""
    return type(part).__module__.partition(".")[0] in ("meanfield", "analysis")


@contextmanager
def _stop_between_steps() -> Iterator[Callable[[], bool]]:
    """While a run steps: the first Ctrl-C (SIGINT) or SIGTERM asks it to stop after the current step.

    The signal only sets a flag that :meth:`ClosedLoop.run` reads between steps, so a step is
    never cut in half (a signal landing inside a compiled call, or between two appends of a
    recorded frame, would leave the state or the frames inconsistent).  A second signal
    interrupts at once, as Python's default handler does.  Outside the main thread (where
    handlers cannot be installed) signals behave as Python's defaults.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    requested: list[int] = []

    def handler(signum: int, frame: object) -> None:
        if requested:
            raise KeyboardInterrupt(f"signal {signum}")
        requested.append(signum)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: bool(requested)
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def signals_deferred() -> Iterator[Callable[[], bool]]:
    """While the results of a finished run are measured and saved: the first Ctrl-C (SIGINT) or
    SIGTERM is held until the block ends, so that no run is lost half-written; a second one
    interrupts at once (Python's ``KeyboardInterrupt``).  Yields whether a signal was held.

    :meth:`ClosedLoop.run` installs its own handler while it steps (a signal then stops the run
    between two steps, ``status = "interrupted"``) and gives this one back after its last step,
    so that the summary and the save (about 40 % of a paper run's wall time) finish.  Outside the
    main thread signals behave as Python's defaults.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    held: list[int] = []

    def handler(signum: int, frame: object) -> None:
        if held:
            raise KeyboardInterrupt(f"signal {signum}")
        held.append(signum)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: bool(held)
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def run(
    scenario: Scenario | str, *, seed: int | None = None, progress: bool = True, **overrides: Any
) -> SimulationResult:
    """Assemble a scenario's closed loop and run it.

    Parameters
    ----------
    scenario : Scenario or str
        A scenario, a built-in name (``"paper"``) or a TOML path.
    seed : int, optional
        Override the scenario's seed.
    progress : bool
        Show a progress bar.
    **overrides
        Passed to :func:`~meanfield.simulation.assembly.assemble` (``sigma``, ``disturbance``,
        ``beta_gamma``, ``kernel``, ``crowd``, ``controller``).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if seed is not None:
        scenario = scenario.replace(seed=seed)
    return ClosedLoop(scenario, **overrides).run(progress=progress)
