"""Write reports/vega/offline.html: the page `dvc plots show` fills (.dvc/config `plots.html_template`),
with vega, vega-lite and vega-embed inlined so that the plots render without network access (DVC's
own page loads them from a CDN). The packages come from the npm registry (`npm pack`), at the
versions DVC's page names; their licence texts go to reports/vega/LICENSE.

    python scripts/vega_offline.py        # needs npm and the registry; run again to change versions
"""

import subprocess
import tarfile
import tempfile
from pathlib import Path

PACKAGES = {
    "vega": "5.20.2",
    "vega-lite": "5.2.0",
    "vega-embed": "6.18.2",
}  # dvc-render 1.0's CDN versions
OUT = Path(__file__).resolve().parents[1] / "reports" / "vega"

PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
{{refresh_tag}}
<title>DVC plots</title>
<!-- Written by scripts/vega_offline.py. Each script below is the package's build/<name>.min.js from
     the npm registry, unchanged; BSD-3-Clause, copyright University of Washington Interactive Data
     Lab; licence texts in reports/vega/LICENSE. -->
{scripts}
<style>table {{ border-spacing: 15px; }}</style>
</head>
<body>
{{plot_divs}}
</body>
</html>
"""


def main() -> None:
    scripts, licences = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for name, version in PACKAGES.items():
            subprocess.run(
                ["npm", "pack", "--silent", f"{name}@{version}"],
                cwd=tmp,
                check=True,
                capture_output=True,
            )
            with tarfile.open(Path(tmp) / f"{name}-{version}.tgz") as tar:
                js = tar.extractfile(f"package/build/{name}.min.js").read().decode()
                licence = tar.extractfile("package/LICENSE").read().decode()
            assert "</script" not in js.lower(), f"{name}: cannot be inlined"
            scripts.append(f"<!-- {name} {version} (npm), BSD-3-Clause -->\n<script>{js}</script>")
            licences.append(
                f"{name} {version} (https://www.npmjs.com/package/{name})\n\n{licence.strip()}\n"
            )
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "offline.html").write_text(PAGE.format(scripts="\n".join(scripts)))
    (OUT / "LICENSE").write_text(("\n" + "-" * 72 + "\n\n").join(licences))
    print(f"wrote {OUT / 'offline.html'} and {OUT / 'LICENSE'}")


if __name__ == "__main__":
    main()
