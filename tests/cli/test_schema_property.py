"""Any value in any scenario field ends well (issue 41, item 3): a refusal naming a field (exit 2, one line) or one
complete run whose ``summary.json`` is strict JSON; never a crash, a traceback, a hang or an empty output folder.

Hypothesis draws a field of any section (or of the top level) and a value of any type, strings, floats (huge, tiny,
NaN, infinite, negative), integers, booleans, lists and tables, and runs ``meanfield run`` on a short paper room
with it.  ``MEANFIELD_SCHEMA_EXAMPLES`` sets the number of examples (default 60 in the suite; 2,000 or more on
demand: ``MEANFIELD_SCHEMA_EXAMPLES=2000 python -m pytest tests/cli/test_schema_property.py``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import os
import signal

from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from meanfield.cli.app import main
from meanfield.scenarios.scenario import Scenario, load_scenario
from meanfield.scenarios.sections import SECTIONS

EXAMPLES = int(os.environ.get("MEANFIELD_SCHEMA_EXAMPLES", "60"))
SECONDS_PER_RUN = 300
"""A run longer than this is a hang (a short paper run takes about a second)."""
T_FINAL = 0.03
SMALLEST_STEP = 3e-6
"""A ``dt`` below this is skipped: it is allowed (up to 10⁹ steps, ``meanfield.simulation.preflight.MAX_STEPS``) and
runs, for minutes, as asked; not a hang."""

KEYS = sorted(
    [f"{section}.{f.name}" for section, spec in SECTIONS.items() for f in dataclasses.fields(spec)]
    + [f.name for f in dataclasses.fields(Scenario) if f.name not in SECTIONS and f.name != "domain"]
    + ["domain.kind", "domain.width", "domain.exits", "domain.wkt", "domain.radius"]
)


def _toml(value) -> str:
    """``value`` as a TOML value (``--set KEY=VALUE`` reads TOML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()) + "}"
    raise TypeError(value)


numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e-9, 1e-3, 0.5, 1.0, 2.0, 10.0, 1e6, 1e300, -1.0]),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.integers(min_value=-3, max_value=50),
)
scalars = st.one_of(
    numbers, st.booleans(), st.text(max_size=12), st.sampled_from(["", "none", "auto", "0.5", "5", "inf", "nan"])
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.sampled_from(["a", "n", "law", "x"]), inner, max_size=2)
    ),
    max_leaves=4,
)


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang(f"a run took more than {SECONDS_PER_RUN} s")


def _strict(text: str) -> dict:
    def refuse(constant: str):
        raise ValueError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def _base_value(key: str):
    """The base scenario's own value of ``key`` (None where it has none)."""
    d = load_scenario("paper").to_dict()
    for part in key.split("."):
        if not isinstance(d, dict) or part not in d:
            return None
        d = d[part]
    return d


def _near(value) -> st.SearchStrategy:
    """Values of the field's own type around its value: the runs that get past the checks, with extreme settings."""
    if isinstance(value, bool):
        return st.booleans()
    if isinstance(value, int):
        return st.one_of(st.integers(min_value=-2, max_value=3 * value + 10), st.just(value * 1000))
    if isinstance(value, float):
        return st.sampled_from([0.0, -value] + [value * f for f in (1e-6, 1e-2, 0.5, 2.0, 1e2, 1e6)])
    if isinstance(value, list) and value and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        return st.lists(_near(value[0]), min_size=len(value), max_size=len(value))
    return values


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_any_value_of_any_field_is_refused_naming_a_field_or_runs_to_a_strict_summary(data, tmp_path_factory):
    key = data.draw(st.sampled_from(KEYS), label="key")
    value = data.draw(st.one_of(values, _near(_base_value(key))), label="value")
    small = isinstance(value, int | float) and not isinstance(value, bool) and 0 < value < SMALLEST_STEP
    assume(not (key == "dt" and small))
    out = tmp_path_factory.mktemp("run") / "out"
    argv = ["run", "paper", "--out", str(out), "--quiet", "--no-figures",
            "--set", f"t_final={T_FINAL}", "--set", "crowd.n=20", "--set", f"{key}={_toml(value)}"]  # fmt: skip
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(SECONDS_PER_RUN)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    text = err.getvalue()
    event(f"exit {code}")
    assert "Traceback" not in text, text
    if code == 2:
        lines = [ln for ln in text.strip().splitlines() if not ln.startswith("meanfield: warning:")]
        assert len(lines) == 1 and lines[0].startswith("meanfield: error: invalid "), text
        assert not (out / "summary.json").exists()
        assert not out.exists() or not any(out.iterdir()), sorted(p.name for p in out.iterdir())  # nothing left
        return
    assert code in (0, 1), (code, text)  # 1: the run diverged, and says so in a complete folder
    summary = _strict((out / "summary.json").read_text())
    assert summary["status"] == ("completed" if code == 0 else "diverged"), summary["status"]
