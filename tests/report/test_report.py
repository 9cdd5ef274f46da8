"""`sensorplan report`: every figure, a self-contained HTML page that a real browser renders,
and the markdown summary."""

from __future__ import annotations

import base64
import html
import math
import re
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sensorplan import study as studies
from sensorplan.errors import ConfigError
from sensorplan.report import FIGURES, OPTIONAL_FIGURES, write_report
from sensorplan.study import parse_study

ROOT = Path(__file__).resolve().parents[2]

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


#: The figures of this study: the horizon figure applies, the per-run GOSPA of changing sets
#: does not (known targets only; tests/report/test_set_report.py has one that does).
SHOWN = [name for name in FIGURES if name != "gospa_runs"]


def test_every_figure_is_written(report: object, study_dir: Path) -> None:
    figs = report.figures                                          # type: ignore[attr-defined]
    assert set(figs) == set(SHOWN)
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
    assert len(srcs) == len(SHOWN)
    for src in srcs:
        assert src.startswith("data:image/png;base64,")
        png_size(base64.b64decode(src.split(",", 1)[1]))


def test_markdown_summary_has_the_tables(report: object) -> None:
    md = report.markdown.read_text(encoding="utf-8")               # type: ignore[attr-defined]
    for name in parse_study(STUDY).method_names:
        assert name.replace("|", "\\|") in md
    for heading in ("## Methods", "## Position RMSE and lost tracks", "## Paired differences",
                    "## Planning time and convergence", "## Track consistency",
                    "## Single runs", "*against myopic", "*against random"):
        assert heading in md
    # Three runs: every interval table says that its intervals are unreliable.
    assert "*all targets (n = 3 runs < 10: intervals unreliable)*" in md
    assert "*against myopic (n = 3 runs < 10: intervals unreliable)*" in md
    for png in SHOWN:
        assert f"]({png}.png)" in md
    assert "gospa_runs.png" not in md
    # The methods table has a column per method setting that differs between methods, from
    # the settings' declarations; the shared ones are listed once.
    assert "| method | planner | K | visibility | miss update | vs myopic | vs random |" in md
    assert "| paper/myopic | pg | 1 | mean | none | – | paper/random |" in md
    assert "Every method: e 2; execution olf; objective cumulative; detection in planning aware;" \
        " occlusion in planning aware; tracker known; model imm;" in md
    # The RMSE table row of a method: mean [lo, hi] and median [lo, hi] (n = 3: no median
    # interval at 95 %, so the median is shown alone).
    assert re.search(r"\| ours/myopic \| \d+\.\d \[-?\d+\.\d, \d+\.\d\] \| \d+\.\d \|", md)


# ------------------------------------------------------------------------ headline


def _per_run_rmse(study_dir: Path) -> dict[str, np.ndarray]:
    """RMSE over all targets and steps 1..S of every run, per method (from the table)."""
    import pandas as pd

    steps = pd.read_parquet(study_dir / "steps.parquet")
    steps = steps[steps["step"] >= 1]
    out = {}
    for name in parse_study(STUDY).method_names:
        g = steps[steps["method"] == name]
        out[name] = np.array([math.sqrt(np.mean(g.loc[g["run"] == r, "error"] ** 2))
                              for r in sorted(g["run"].unique())])
    return out


def _t95(d: np.ndarray) -> tuple[float, float, float]:
    from scipy import stats

    lo, hi = stats.t.interval(0.95, d.size - 1, loc=d.mean(), scale=stats.sem(d))
    return float(d.mean()), float(lo), float(hi)


def test_headline_against_a_second_computation(study_dir: Path) -> None:
    from sensorplan.report.headline import headline
    from sensorplan.study import load_study_dir, paired_differences, run_metrics, summary

    t = load_study_dir(study_dir)
    metrics = run_metrics(t)
    h = headline(t.study, metrics, summary(metrics), paired_differences(metrics, t.study))
    per_run = _per_run_rmse(study_dir)
    means = {k: v.mean() for k, v in per_run.items()}
    ranked = sorted(means, key=means.get)
    assert h.kind == "all" and h.best == ranked[0] and h.runner_up == ranked[1]
    np.testing.assert_allclose([h.best_rmse.mean, h.best_rmse.lo, h.best_rmse.hi],
                               _t95(per_run[h.best]), rtol=1e-10)
    np.testing.assert_allclose([h.vs_runner_up.mean, h.vs_runner_up.lo, h.vs_runner_up.hi],
                               _t95(per_run[h.best] - per_run[ranked[1]]), rtol=1e-10)
    # The random reference of an "ours" method is ours/random (same tracker).
    assert h.random == ("ours/random" if h.best.startswith("ours/") else "paper/random")
    np.testing.assert_allclose([h.vs_random.mean, h.vs_random.lo, h.vs_random.hi],
                               _t95(per_run[h.best] - per_run[h.random]), rtol=1e-10)
    # Lookahead: the better of the two K > 1 methods, against ours/myopic.
    look = min(("ours/olf K=2", "ours/olf K=3 <&>"), key=means.get)
    assert (h.lookahead, h.myopic) == (look, "ours/myopic")
    np.testing.assert_allclose([h.vs_myopic.mean, h.vs_myopic.lo, h.vs_myopic.hi],
                               _t95(per_run[look] - per_run["ours/myopic"]), rtol=1e-10)
    assert h.small_sample                                    # 3 runs


@pytest.mark.parametrize("lo, hi, verdict", [(-3.0, -1.0, "paid"), (1.0, 3.0, "lost"),
                                             (-1.0, 2.0, "inconclusive")])
def test_headline_says_whether_lookahead_paid(lo: float, hi: float, verdict: str) -> None:
    from sensorplan.report.headline import Headline, Interval, headline_paragraphs

    iv = Interval(0.5 * (lo + hi), lo, hi, 20)
    h = Headline(kind="all", best="A", best_rmse=Interval(10.0, 8.0, 12.0, 20),
                 runner_up="B", vs_runner_up=Interval(-1.0, -2.0, 0.5, 20), random="R",
                 vs_random=Interval(-9.0, -12.0, -6.0, 20), lookahead="L K=3", myopic="M",
                 vs_myopic=iv, better_share=0.4)
    assert h.verdict == verdict
    text = " ".join(headline_paragraphs(h, "../docs/results.md"))
    assert "**Best method: A**" in text and "(not significant)" in text
    assert "(significant)" in text                             # against random
    assert "n < 10" not in text
    linked = "[docs/results.md](../docs/results.md)" in text
    assert linked == (verdict != "paid")
    assert ("Lookahead paid" in text) == (verdict == "paid")
    no_link = " ".join(headline_paragraphs(h, None))
    assert ("docs/results.md (in the sensorplan source)" in no_link) == (verdict != "paid")


def test_headline_without_a_lookahead_method_or_interval() -> None:
    from sensorplan.report.headline import Headline, Interval, headline_paragraphs

    h = Headline(kind="cv", best="A", best_rmse=Interval(10.0, math.nan, math.nan, 1),
                 runner_up="B", vs_runner_up=Interval(-0.01, math.nan, math.nan, 1),
                 random=None, vs_random=None, lookahead=None, myopic=None, vs_myopic=None,
                 small_sample=True)
    assert h.verdict is None
    first, second = headline_paragraphs(h, None)
    assert "over cv targets 10.0 m (95 % t-interval, 1 paired run)" in first
    assert "+0.0 m against the runner-up, B (no interval)" in first       # never "-0.0"
    assert "(n < 10: intervals unreliable.)" in first
    assert "not tested here" in second


def test_report_page_starts_with_the_headline_and_contents(report: object) -> None:
    page = report.html.read_text(encoding="utf-8")                 # type: ignore[attr-defined]
    top = page.index('<section id="headline"')
    assert top < page.index("<h2") and top < page.index('<nav id="contents"')
    assert "Best method: " in page[top:page.index("</section>", top)]
    targets = re.findall(r'<nav id="contents".*?</nav>', page, re.S)[0]
    links = re.findall(r'href="#([^"]+)"', targets)
    assert len(links) == len(re.findall(r"<h2 ", page)) >= 7
    for anchor in links:
        assert f'id="{anchor}"' in page
    md = report.markdown.read_text(encoding="utf-8")               # type: ignore[attr-defined]
    assert md.splitlines()[2].startswith("> **Best method: ")
    assert "**Contents:** [Methods](#methods)" in md
    # The single-runs table names a replay command of the best method's worst run.
    assert re.search(r"`sensorplan replay \S+ --run \d+ --method ", md)


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
        pytest.skip("no Chromium on this machine, so the HTML was not rendered in a browser "
                    "(`make browser` installs one: it runs apt-get as root)")
    return browser


def browser_flags(profile: Path) -> list[str]:
    return ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--disable-dev-shm-usage", "--host-resolver-rules=MAP * ~NOTFOUND",
            f"--user-data-dir={profile}", "--virtual-time-budget=10000",
            "--window-size=1200,3000"]


#: Appended to a copy of the page: the page's full height and where the headline is.
LAYOUT_SCRIPT = """<script>
window.addEventListener("load", function () {
  var h = document.getElementById("headline");
  document.body.setAttribute("data-layout", document.documentElement.scrollHeight + "/" +
                             Math.round(h.getBoundingClientRect().top));
});
</script>
"""


def test_html_renders_in_headless_chromium(report: object, chromium: str,
                                           tmp_path: Path) -> None:
    page = report.html                                             # type: ignore[attr-defined]
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text(encoding="utf-8").replace(
        "</body>", MARKER_SCRIPT + LAYOUT_SCRIPT + "</body>"), encoding="utf-8")
    dom = subprocess.run([chromium, *browser_flags(tmp_path / "profile1"), "--dump-dom",
                          probe.as_uri()], capture_output=True, text=True, timeout=120)
    found = re.search(r'data-images-loaded="(\d+)/(\d+)"', dom.stdout)
    assert found, f"no load marker in the DOM (exit {dom.returncode}): {dom.stderr[-2000:]}"
    ok, total = int(found.group(1)), int(found.group(2))
    assert total == len(SHOWN) and ok == total, f"{ok} of {total} images loaded"
    # The rendered DOM has the headline near the top of the page.
    assert "Best method: " in dom.stdout and "Lookahead" in dom.stdout
    height, headline_top = map(int, re.search(r'data-layout="(\d+)/(-?\d+)"',
                                              dom.stdout).groups())
    assert 0 < headline_top < 200, headline_top
    assert height > 4000, height                   # nine figures and a dozen tables

    # A full-page screenshot: the window as tall as the page.
    shot = tmp_path / "report.png"
    flags = [f for f in browser_flags(tmp_path / "profile2") if not f.startswith("--window")]
    res = subprocess.run([chromium, *flags, f"--window-size=1280,{height}",
                          f"--screenshot={shot}", page.as_uri()], capture_output=True,
                         text=True, timeout=180, check=False)
    assert shot.exists(), f"no screenshot (exit {res.returncode}): {res.stderr[-2000:]}"
    assert png_size(shot.read_bytes()) == (1280, height)
    from PIL import Image

    with Image.open(shot) as im:
        pixels = np.asarray(im.convert("RGB").reduce(4))
    ink = np.any(pixels < 200, axis=2)
    # Not blank: text, tables and figures cover a good part of the page, everywhere down it.
    assert ink.mean() > 0.03, ink.mean()
    bands = np.array_split(ink, 8, axis=0)
    assert all(b.mean() > 0.005 for b in bands), [round(b.mean(), 4) for b in bands]
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 500
    # The headline box is drawn: its background tint is there at the top of the page.
    top = pixels[: 300 // 4]
    assert np.any(np.all(top == (0xf4, 0xf7, 0xfb), axis=2))


def test_the_readme_commands_install_no_system_package() -> None:
    # make demo and make test stay inside .venv; a browser is an explicit step (make browser).
    for target in ("demo", "test"):
        planned = subprocess.run(["make", "-n", "-B", target], cwd=ROOT, capture_output=True,
                                 text=True, timeout=60, check=True).stdout
        assert "apt-get" not in planned and "ensure_chromium" not in planned, target
    # nor does the browser test's setup
    text = Path(__file__).read_text()
    fixture = text[text.index("def chromium()"):text.index("def browser_flags")]
    assert "subprocess" not in fixture               # it runs nothing, it only looks


def test_the_header_counts_targets_only_where_they_are_known() -> None:
    # With births the scenario's targets are the templates born targets take, not a count:
    # the header said "5 targets" of the search preset, which starts with 3 and has more.
    from sensorplan.report.document import population_text
    from sensorplan.simulation.scenario import PRESETS

    paper, search, vo12 = PRESETS["paper"](), PRESETS["search"](), PRESETS["vo12"]()
    assert population_text(paper).startswith(f"{len(paper.targets)} targets (")
    text = population_text(search)
    assert text.startswith(f"{search.n_initial} targets at the start, ")
    assert f"{search.birth_rate:g} births a step at the map's edges" in text
    assert f"{len(search.targets)} templates" in text
    assert population_text(vo12).startswith("the vo12 truth")
