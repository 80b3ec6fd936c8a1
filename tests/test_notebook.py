"""The tutorial notebook runs from start to end; meanfield leaves the notebook's backend alone (issue 16, item 7)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_tutorial_notebook_runs():
    import nbclient  # the test extra installs nbformat, nbclient and ipykernel
    import nbformat

    nb = nbformat.read(ROOT / "docs" / "notebooks" / "tutorial.ipynb", as_version=4)
    where = {"metadata": {"path": str(ROOT)}}  # the notebook imports docs/examples/ from the root
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources=where).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 4  # Fig. 2, Fig. 3, V2, the final density: drawn inline
    assert "inline" in outputs[0]["data"]["text/plain"]  # the notebook's own backend, kept to the end


def test_drawing_and_saving_a_run_changes_no_backend_and_leaves_no_pyplot_figure(tmp_path):
    code = f"""
import matplotlib
matplotlib.use("pdf")
import matplotlib.pyplot as plt
from meanfield import paper_scenario, run
from meanfield.plotting.figures import save_run_figures
import analysis.figures, analysis.pedestrians.figures, verification
r = run(paper_scenario(seed=0).replace(t_final=0.05), progress=False)
r.save({str(tmp_path)!r}, artifacts=[save_run_figures])
assert matplotlib.get_backend() == "pdf", matplotlib.get_backend()
assert plt.get_fignums() == [], plt.get_fignums()
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
    assert (tmp_path / "snapshots.png").read_bytes()[:4] == b"\x89PNG"
