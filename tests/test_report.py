"""`sensorplan report`: every figure, a self-contained HTML page that a real browser renders,
and the markdown summary."""

from __future__ import annotations

import base64
import html
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from sensorplan import study as studies
from sensorplan.errors import ConfigError
from sensorplan.study import parse_study
from sensorplan.report import FIGURES, OPTIONAL_FIGURES, write_report

ROOT = Path(__file__).resolve().parents[1]

#: K = 1, 2, 3 of one configuration (the horizon figure), the paper's configuration and
#: random references; names with characters that HTML must escape.
STUDY = """
description = "tiny report study"
runs = 3
steps = 12
seed = 5
[defaults]
steps_per_epoch = 2
[[methods]]
name = "ours/myopic"
planner = "pg"
[[methods]]
name = "ours/olf K=2"
planner = "pg"
horizon = 2
[[methods]]
name = "ours/olf K=3 <&>"
planner = "pg"
horizon = 3
[[methods]]
name = "ours/random"
planner = "random"
[[methods]]
name = "paper/myopic"
planner = "pg"
visibility = "mean"
[methods.tracker]
miss_update = "none"
[[methods]]
name = "paper/random"
planner = "random"
[methods.tracker]
miss_update = "none"
"""


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report") / "study"
    studies.run_study(parse_study(STUDY), out, workers=1)
    return out


@pytest.fixture(scope="module")
def report(study_dir: Path) -> object:
    return write_report(study_dir)


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    return struct.unpack(">II", data[16:24])


def test_every_figure_is_written(report: object, study_dir: Path) -> None:
    figs = report.figures                                          # type: ignore[attr-defined]
    assert set(figs) == set(FIGURES)                # the horizon figure applies here
    for name, path in figs.items():
        assert path.parent == study_dir / "report"
        w, h = png_size(path.read_bytes())
        assert w >= 600 and h >= 250, (name, w, h)
    assert set(OPTIONAL_FIGURES) <= set(FIGURES)


def test_html_is_self_contained_and_names_every_method(report: object) -> None:
    page = report.html.read_text(encoding="utf-8")                 # type: ignore[attr-defined]
    study = parse_study(STUDY)
    for name in study.method_names:
        assert html.escape(name) in page, name
    assert "ours/olf K=3 &lt;&amp;&gt;" in page
    # No network: nothing is fetched from a URL, every image is an embedded PNG.
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", page)
    srcs = re.findall(r'<img src="([^"]+)"', page)
    assert len(srcs) == len(FIGURES)
    for src in srcs:
        assert src.startswith("data:image/png;base64,")
        png_size(base64.b64decode(src.split(",", 1)[1]))


def test_markdown_summary_has_the_tables(report: object) -> None:
    md = report.markdown.read_text(encoding="utf-8")               # type: ignore[attr-defined]
    for name in parse_study(STUDY).method_names:
        assert name.replace("|", "\\|") in md
    for heading in ("## Methods", "## Position RMSE and lost tracks", "## Paired differences",
                    "## Planning time and convergence", "*against myopic*", "*against random*"):
        assert heading in md
    for png in FIGURES:
        assert f"]({png}.png)" in md
    # The methods table has a column per method setting that differs between methods, from
    # the settings' declarations; the shared ones are listed once.
    assert "| method | planner | K | visibility | miss update | vs myopic | vs random |" in md
    assert "| paper/myopic | pg | 1 | mean | none | – | paper/random |" in md
    assert "Every method: e 2; execution olf; objective terminal; detection in planning aware;" \
        " model imm;" in md
    # The RMSE table row of a method: mean [lo, hi] and median [lo, hi] (n = 3: no median
    # interval at 95 %, so the median is shown alone).
    assert re.search(r"\| ours/myopic \| \d+\.\d \[-?\d+\.\d, \d+\.\d\] \| \d+\.\d \|", md)


def test_report_of_an_unfinished_study(study_dir: Path, tmp_path: Path) -> None:
    partial = tmp_path / "partial"
    shutil.copytree(study_dir, partial)
    for table in studies.TABLES:
        (partial / f"{table}.parquet").unlink()
    studies.part_path(partial, 2, 1, "steps").unlink()                  # run 2 unfinished
    files = write_report(partial)
    assert not files.complete and files.runs == 2
    assert "study unfinished" in files.markdown.read_text()


def test_report_of_a_non_study_directory_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        write_report(tmp_path)
    assert info.value.field == "DIR"


# ------------------------------------------------------------------------- browser

#: Appended to a copy of the page: records how many images finished loading with pixels.
MARKER_SCRIPT = """<script>
window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute("data-images-loaded", ok + "/" + imgs.length);
});
</script>
"""


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None


@pytest.fixture(scope="module")
def chromium() -> str:
    browser = find_chromium()
    if browser is None:
        # The test setup's installer (a no-op unless root with apt-get); make test runs it too.
        subprocess.run(["bash", str(ROOT / "scripts" / "ensure_chromium.sh")], timeout=900,
                       check=False)
        browser = find_chromium()
    if browser is None:
        pytest.skip("no Chromium and none could be installed (scripts/ensure_chromium.sh "
                    "needs root and apt-get); the HTML was not rendered")
    return browser


def browser_flags(profile: Path) -> list[str]:
    return ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--disable-dev-shm-usage", "--host-resolver-rules=MAP * ~NOTFOUND",
            f"--user-data-dir={profile}", "--virtual-time-budget=10000",
            "--window-size=1200,3000"]


def test_html_renders_in_headless_chromium(report: object, chromium: str,
                                           tmp_path: Path) -> None:
    page = report.html                                             # type: ignore[attr-defined]
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>",
                                                              MARKER_SCRIPT + "</body>"),
                     encoding="utf-8")
    dom = subprocess.run([chromium, *browser_flags(tmp_path / "profile1"), "--dump-dom",
                          probe.as_uri()], capture_output=True, text=True, timeout=120)
    found = re.search(r'data-images-loaded="(\d+)/(\d+)"', dom.stdout)
    assert found, f"no load marker in the DOM (exit {dom.returncode}): {dom.stderr[-2000:]}"
    ok, total = int(found.group(1)), int(found.group(2))
    assert total == len(FIGURES) and ok == total, f"{ok} of {total} images loaded"

    shot = tmp_path / "report.png"
    res = subprocess.run([chromium, *browser_flags(tmp_path / "profile2"),
                          f"--screenshot={shot}", page.as_uri()], capture_output=True,
                         text=True, timeout=120)
    assert shot.exists(), f"no screenshot (exit {res.returncode}): {res.stderr[-2000:]}"
    assert png_size(shot.read_bytes()) == (1200, 3000)
