"""`dvc plots show` with the repository's plots (dvc.yaml) and page (.dvc/config
plots.html_template = reports/vega/offline.html): every plot colours its series one each, and the
page loads no script from the network (vega, vega-lite and vega-embed are inlined)."""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DVC = Path(sys.executable).with_name("dvc")
PLOTS = yaml.safe_load((ROOT / "dvc.yaml").read_text())["plots"]


def test_the_offline_page_inlines_vega():
    page = (ROOT / "reports" / "vega" / "offline.html").read_text()
    assert (
        "{plot_divs}" in page and "{scripts}" not in page
    )  # DVC's CDN script tags have nowhere to go
    for name in ("vega 5", "vega-lite 5", "vega-embed 6"):
        assert f"<!-- {name}" in page
    assert not re.search(r"<script[^>]+src=", page)
    assert "Interactive Data Lab" in (ROOT / "reports" / "vega" / "LICENSE").read_text()


@pytest.mark.skipif(not DVC.exists() and shutil.which("dvc") is None, reason="dvc is not installed")
def test_plots_render_offline_with_one_colour_per_series(tmp_path):
    dvc = str(DVC) if DVC.exists() else shutil.which("dvc")
    out = subprocess.run(
        [dvc, "plots", "show", "-o", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    page = (tmp_path / "index.html").read_text()
    assert not re.search(r"<script[^>]+src=[\"']?https?:", page), (
        "the page loads scripts from the network"
    )
    specs = [
        json.loads(s) for s in re.findall(r"var spec = (\{.*?\});\s*vegaEmbed", page, re.DOTALL)
    ]
    assert len(specs) == len(PLOTS)
    for spec in specs:
        color = spec["encoding"]["color"]
        assert color["field"] == "series" and color["scale"]["range"] == {"field": "colour"}
        assert color["legend"]["labelLimit"] == 0  # names are not cut
        rows = spec["data"]["values"]
        assert len({row["series"] for row in rows}) >= 2, spec["title"]
        # Vega-Lite takes the range from the distinct colours sorted by series, the domain sorted
        # by name: they line up only when every series of a plot has a colour of its own
        colours = {(row["series"], row["colour"]) for row in rows}
        assert len(colours) == len({s for s, _ in colours}) == len({c for _, c in colours})
        assert "sort" not in color and len({row["maze"] for row in rows}) == 1  # a maze a plot
