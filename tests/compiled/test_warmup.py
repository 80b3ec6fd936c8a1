"""The first compile on two cores (``meanfield._compiled.warmup``): forked children fill numba's cache.

Each test runs a fresh Python process on its own empty ``NUMBA_CACHE_DIR``, the only way to
see a cold cache. What is checked: the children compile and cache the loops the parent does
not call itself; the run's numbers are the same with and without them; nothing is forked on
a warm cache or when ``MEANFIELD_PARALLEL_COMPILE=0``; a task that fails or hangs costs the
parent nothing but the wait (bounded by ``timeout``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import threading

import pytest

from meanfield._compiled import core as compiled
from meanfield._compiled import warmup

pytestmark = pytest.mark.skipif(
    not (compiled.numba_available() and sys.platform.startswith("linux") and warmup._usable_cpus() >= 2),
    reason="the parallel compile needs numba, Linux and two usable CPUs",
)

BUILD = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from meanfield import ClosedLoop, paper_scenario
    from meanfield._compiled import warmup
    from meanfield.controllers import _law_loops as law_loops
    loop = ClosedLoop(paper_scenario(seed=3).replace(t_final=0.05))
    forked, law_called = warmup._used, law_loops.paper_law._jitted is not None
    for _ in range(5):
        loop.step()
    stats = law_loops.paper_law._jitted.stats  # numba's: what this process read from the cache, what it compiled
    law_read = sum(stats.cache_hits.values()) > 0 and not stats.cache_misses
    print(json.dumps({"forked": forked, "law_called_here": law_called, "law_read_from_cache": law_read,
                      "density": loop.density.ravel().tolist(), "robots": loop.robots.positions.ravel().tolist()}))
    """
)


def _python(code: str, cache: str, args: tuple[str, ...] | list[str] = (), **env: str) -> dict:
    environment = {**os.environ, "NUMBA_CACHE_DIR": cache, "MEANFIELD_COMPILED": "1", **env}
    environment.pop(warmup.ENV, None)
    environment.update(env)
    command = [sys.executable, "-c", code, *args]
    out = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _script(tmp_path, name: str, code: str, *args: str, **env: str) -> tuple[dict, str]:
    """``code`` run as the file ``name``.py (numba caches a loop only if its source is a file), on its own empty
    cache: the JSON of its last line of output, and its stderr."""
    script = tmp_path / f"{name}.py"
    script.write_text(code)
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / name), "MEANFIELD_COMPILED": "1"}
    environment.pop(warmup.ENV, None)
    environment.update(env)
    out = subprocess.run([sys.executable, str(script), *args], env=environment, capture_output=True, text=True,
                         timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


def test_children_cache_the_law_the_parent_has_not_called_and_the_numbers_do_not_change(tmp_path):
    parallel = _python(BUILD, str(tmp_path / "a"))
    assert parallel["forked"]
    # the parent had not called the law when it forked, yet it read the law's compiled code from the cache,
    # never compiling it: a child wrote it (the first act waited for the children)
    assert not parallel["law_called_here"] and parallel["law_read_from_cache"]
    serial = _python(BUILD, str(tmp_path / "b"), MEANFIELD_PARALLEL_COMPILE="0")
    assert not serial["forked"] and not serial["law_read_from_cache"]
    assert parallel["density"] == serial["density"]  # bit for bit: the children change nothing here
    assert parallel["robots"] == serial["robots"]


FOKKER_PLANCK = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from meanfield import ClosedLoop, paper_scenario
    from meanfield._compiled import warmup
    from meanfield.signs.robots import limited_inputs
    sc = paper_scenario(seed=3).with_values({"pedestrians.backend": "fokker-planck"}).replace(t_final=0.05)
    if sys.argv[1] == "robots-first":  # the saturation and the robots' step compiled before: the build compiles nothing
        from meanfield.simulation.assembly import assemble
        parts = assemble(sc)
        n = len(parts.robots.positions)
        limited_inputs(np.zeros((n, 2)), np.zeros(n), 1.0, 1.0)
        parts.robots.advance(np.zeros((n, 2)), np.zeros(n), sc.dt, parts.robot_region)
    loop = ClosedLoop(sc)
    forked_at_build = warmup._used
    for _ in range(5):
        loop.step()
    print(json.dumps({"forked_at_build": forked_at_build, "forked": warmup._used,
                      "density": loop.density.ravel().tolist(), "robots": loop.robots.positions.ravel().tolist()}))
    """
)


def test_a_build_that_compiles_nothing_forks_the_plant_beside_the_first_act(tmp_path):
    # the PDE's first density compiles nothing; the build still compiles the robots' saturation and step, and forks
    at_build = _python(FOKKER_PLANCK, str(tmp_path / "fp"), args=["plain"])
    assert at_build["forked_at_build"] and at_build["forked"]
    # with those compiled before, the build compiles nothing and forks nothing; the first step's act does
    at_act = _python(FOKKER_PLANCK, str(tmp_path / "fp0"), args=["robots-first"])
    assert not at_act["forked_at_build"] and at_act["forked"]
    serial = _python(FOKKER_PLANCK, str(tmp_path / "fp1"), MEANFIELD_PARALLEL_COMPILE="0", args=["plain"])
    assert not serial["forked"]
    for run in (at_build, at_act):  # bit for bit
        assert run["density"] == serial["density"] and run["robots"] == serial["robots"]


def test_nothing_is_forked_on_a_warm_cache(tmp_path):
    cache = str(tmp_path / "c")
    assert _python(BUILD, cache)["forked"]
    assert not _python(BUILD, cache)["forked"]


LOOP_AND_TASKS = textwrap.dedent(
    """
    import json, os, sys, time
    import numpy as np
    from meanfield._compiled import warmup
    from meanfield._compiled.core import compiled

    def _twice(x):
        return 2.0 * x

    @compiled(fallback=_twice)
    def twice(x):
        out = np.empty_like(x)
        for i in range(x.shape[0]):
            out[i] = 2.0 * x[i]
        return out

    def fails():
        raise RuntimeError("a task that fails")

    def hangs():
        time.sleep(600)
    """
)
"""A compiled loop to compile in the block, and two tasks for the children: one fails, one hangs."""

TASKS = LOOP_AND_TASKS + textwrap.dedent(
    """

    t0 = time.perf_counter()
    with warmup.compile_in_parallel([fails, hangs], timeout=float(sys.argv[1])):
        y = twice(np.arange(3.0))
    print(json.dumps({"forked": warmup._used, "y": y.tolist(), "seconds": time.perf_counter() - t0}))
    """
)


def test_a_task_that_fails_or_hangs_costs_only_the_bounded_wait(tmp_path):
    doc, stderr = _script(tmp_path, "tasks", TASKS, "2.0")
    assert doc["forked"] and doc["y"] == [0.0, 2.0, 4.0]
    assert doc["seconds"] < 60  # the hanging child was killed at the 2 s timeout, not waited for (600 s)
    assert "a task that fails" not in stderr  # the children's output goes nowhere


DEFERRED = LOOP_AND_TASKS + textwrap.dedent(
    """
    with warmup.compile_in_parallel([hangs], timeout=float(sys.argv[1]), wait=False) as children:
        y = twice(np.arange(3.0))
    pids = list(children.pids)
    running = [os.waitpid(pid, os.WNOHANG)[0] == 0 for pid in pids]  # still running after the block
    t1 = time.perf_counter()
    children.wait()
    waited = time.perf_counter() - t1
    gone = []
    for pid in pids:
        try:
            os.waitpid(pid, os.WNOHANG)
            gone.append(False)
        except ChildProcessError:  # reaped: no such child any more
            gone.append(True)
    print(json.dumps({"pids": len(pids), "running": running, "waited": waited, "gone": gone,
                      "left": len(children.pids), "y": y.tolist()}))
    """
)


def test_a_deferred_wait_lets_the_block_end_at_once_and_reaps_the_children_later(tmp_path):
    doc, _ = _script(tmp_path, "deferred", DEFERRED, "3.0")
    assert doc["pids"] == 1 and doc["running"] == [True]  # the block ended with the hanging child still running
    assert doc["gone"] == [True] and doc["left"] == 0  # wait() killed and reaped it at the timeout
    assert doc["waited"] < 60  # bounded by the timeout (3 s from the block's end), not the child's 600 s
    assert doc["y"] == [0.0, 2.0, 4.0]


def test_the_switch_and_the_conditions():
    assert warmup.ENV == "MEANFIELD_PARALLEL_COMPILE"
    with compiled.numpy_path():
        assert not warmup.parallel_compile_possible()  # nothing compiles on the numpy path
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:  # another thread could hold a lock the child would need: no fork
        assert not warmup.parallel_compile_possible()
    finally:
        release.set()
        other.join()


def test_the_switch_turns_it_off(tmp_path):
    doc, _ = _script(tmp_path, "off", TASKS, "2.0", **{warmup.ENV: "0"})
    assert not doc["forked"] and doc["y"] == [0.0, 2.0, 4.0]


PLUGIN = textwrap.dedent(
    """
    import dataclasses, json, os, sys
    from meanfield import ClosedLoop, paper_scenario
    from meanfield._compiled import warmup
    from meanfield.simulation.assembly import assemble

    class Relay:  # a plug-in controller that could drive real robots: each call leaves a trace
        def __init__(self, inner):
            self.inner = inner

        def act(self, observation):
            with open(sys.argv[1], "a") as f:
                f.write(f"{os.getpid()}\\n")
            return self.inner.act(observation)

    parts = assemble(paper_scenario(seed=0).replace(t_final=0.05))
    loop = ClosedLoop(dataclasses.replace(parts, controller=Relay(parts.controller)))
    loop.step()
    print(json.dumps({"forked": warmup._used, "pid": os.getpid()}))
    """
)


def test_a_plugin_controller_is_never_called_in_a_child(tmp_path):
    script, trace = tmp_path / "plugin.py", tmp_path / "calls.txt"
    script.write_text(PLUGIN)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "f"), "MEANFIELD_COMPILED": "1"}
    env.pop(warmup.ENV, None)
    command = [sys.executable, str(script), str(trace)]
    out = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    assert doc["forked"]  # the toolkit's crowd still compiled in a child
    assert trace.read_text().split() == [str(doc["pid"])]  # one call, the step's, in this process


def test_meanfield_run_says_when_its_first_run_compiles(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "g"), "MEANFIELD_COMPILED": "1"}
    command = [sys.executable, "-m", "meanfield.cli.app", "run", "paper", "--set", "t_final=0.05", "--no-figures"]

    def stderr(out: str) -> str:
        done = subprocess.run([*command, "--out", str(tmp_path / out)], env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done.stderr

    assert "compiling the toolkit's loops for this machine" in stderr("cold")
    assert "compiling" not in stderr("warm")  # numba's cache serves the second run


def test_a_cold_compile_callback_can_be_withdrawn():
    calls = []

    def callback() -> None:
        calls.append(1)

    unregister = compiled.before_cold_compile(callback)
    assert callback in compiled._before_cold_compile
    unregister()
    unregister()  # twice: no error
    assert callback not in compiled._before_cold_compile and not calls


def test_meanfield_run_leaves_no_callback_behind(tmp_path):
    from meanfield.cli.app import main
    from meanfield.cli.run import _say_compiling

    assert main(["run", "paper", "--set", "t_final=0.05", "--no-figures", "--out", str(tmp_path / "r")]) == 0
    assert _say_compiling not in compiled._before_cold_compile  # (a warm cache never called it)
