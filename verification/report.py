"""Write a verification run: ``report.md`` (a table of claims and verdicts, then a section
per claim with its figures) and ``verdicts.json`` (one entry per claim).

Both files are written atomically (a temporary file renamed into place), ``verdicts.json``
last, so a directory holding it holds a complete report.  An interrupted run writes what it
has, with ``"status": "interrupted"``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from meanfield.io.atomic import atomic_write_json, atomic_write_text
from verification.result import CheckResult, jsonable
from verification.runner import VerificationRun

__all__ = ["write_report", "render_markdown"]

_MARK = {"holds": "✅ holds", "fails": "❌ fails", "inconclusive": "➖ inconclusive", "error": "⚠️ error"}


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.4g}"
    if isinstance(x, dict):
        return ", ".join(f"{k}: {_fmt(v)}" for k, v in x.items())
    if isinstance(x, list):
        return "[" + ", ".join(_fmt(v) for v in x) + "]"
    return str(x)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _section(r: CheckResult) -> list[str]:
    lines = [f"## {r.key}: {_MARK[r.verdict]}", "", f"**Claim.** {r.claim}", ""]
    if r.criterion:
        lines += [f"**Decision rule.** {r.criterion}", ""]
    if r.reason:
        lines += [f"**Reason.** {r.reason}", ""]
    lines += [f"**Result.** {r.summary}", ""]
    if r.measured or r.bound:
        lines += ["| | |", "|---|---|"]
        lines += [f"| measured: {k} | {_cell(_fmt(v))} |" for k, v in r.measured.items()]
        lines += [f"| bound: {k} | {_cell(_fmt(v))} |" for k, v in r.bound.items()]
        lines.append("")
    if r.cases:
        keys: list[str] = []
        for c in r.cases:
            keys += [k for k in c if k not in keys]
        lines += ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
        for c in r.cases:
            lines.append("| " + " | ".join(_cell(_fmt(c.get(k, ""))) for k in keys) + " |")
        lines.append("")
    for fig in r.figures:
        lines += [f"![{r.key}]({fig})", ""]
    lines += [f"*{r.seconds:.1f} s*", ""]
    return lines


def render_markdown(run: VerificationRun) -> str:
    """The text of ``report.md``."""
    lines = [
        f"# Verification report: scenario `{run.scenario_name}`",
        "",
        f"{'Quick' if run.quick else 'Full'} run, {run.seconds:.0f} s, status **{run.status}**. "
        "Verdicts: *holds* — the measured figures meet the claim's bound; *fails* — they do not; "
        "*inconclusive* — a hypothesis of the claim is not met (the reason is given); *error* — the check crashed.",
        "",
        "| claim | verdict | result |",
        "|---|---|---|",
    ]
    for r in run.results:
        lines.append(f"| [{r.key}](#{r.key}) | {_MARK[r.verdict]} | {_cell(r.summary)} |")
    lines.append("")
    for r in run.results:
        lines += _section(r)
    return "\n".join(lines)


def write_report(run: VerificationRun, out_dir: str | Path) -> dict[str, Path]:
    """Write ``report.md`` then ``verdicts.json`` into ``out_dir``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = atomic_write_text(out / "report.md", render_markdown(run))
    data = jsonable(run.to_dict())
    json.dumps(data)  # fail here, before anything is renamed into place, if not serialisable
    js = atomic_write_json(out / "verdicts.json", data)
    return {"report": md, "verdicts": js}
