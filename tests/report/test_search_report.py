"""The report of a study that searches: the stored expected undetected count is the sum of
the replayed run's intensity, the representative run is the one the docs name (recomputed
here from gospa.parquet), the table's numbers are the table's means, the figures are
written; a study that does not search gets exactly the report it got before."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sensorplan import study as studies
from sensorplan.study import parse_study

RUNS, STEPS = 3, 10
STUDY = f"""
runs = {RUNS}
steps = {STEPS}
seed = 11
[scenario]
preset = "search"
[[methods]]
name = "search"
planner = "pg"
search = "on"
[[methods]]
name = "no search"
planner = "pg"
search = "off"
"""


@pytest.fixture(scope="module")
def search_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("search") / "study"
    studies.run_study(parse_study(STUDY), out, workers=1)
    return out


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def test_the_stored_count_is_the_replayed_intensitys_sum(search_study: Path) -> None:
    from sensorplan.study.replay import replay_run
    from sensorplan.study.tables import intensity_steps

    g = pd.read_parquet(search_study / "gospa.parquet")
    for method in ("search", "no search"):
        rep = replay_run(search_study, 1, method)
        mine = g[(g["run"] == 1) & (g["method"] == method)].sort_values("step")
        grid = rep.episode.undetected.astype(np.float64)
        np.testing.assert_allclose(mine["undetected"].to_numpy(),
                                   grid[1:].sum(axis=(1, 2)), rtol=1e-12)
        stored = mine.dropna(subset=["intensity"])
        assert stored["step"].tolist() == intensity_steps(STEPS)
        for t, cells in zip(stored["step"], stored["intensity"]):
            np.testing.assert_array_equal(np.asarray(cells, np.float32),
                                          rep.episode.undetected[t].reshape(-1))


def test_the_report_shows_what_search_did(search_study: Path) -> None:
    from sensorplan.report import write_report

    report = write_report(search_study)
    for name in ("undetected_count", "undetected_maps", "gospa_parts_time"):
        path = report.figures[name]
        w, h = png_size(path)
        assert w >= 600 and h >= 250
        assert path.stat().st_size < 400_000, name          # modest files
    md = report.markdown.read_text(encoding="utf-8")
    assert "## Search: targets not yet detected" in md
    g = pd.read_parquet(search_study / "gospa.parquet")
    # The representative run: nearest (RMS over steps) to the mean curve over runs of the
    # methods' average expected undetected count.
    curves = np.array([[g[(g["run"] == r) & (g["step"] == t)]["undetected"].mean()
                        for t in range(1, STEPS + 1)] for r in range(RUNS)])
    rms = np.sqrt(((curves - curves.mean(axis=0)) ** 2).mean(axis=1))
    run = int(np.argmin(rms))
    assert f"at the stored steps of run {run}, the representative run" in md
    assert f"`sensorplan replay DIR --run {run} --method NAME`" in md
    mine = g[g["method"] == "search"]
    over_steps = mine.groupby("run")["undetected"].mean().mean()
    last = mine[mine["step"] == STEPS]["undetected"].mean()
    assert f"| search | {over_steps:.2f} [" in md
    assert f"] | {last:.2f} [" in md


def test_a_study_without_search_gets_the_report_it_got_before(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorplan.report import document, write_report

    text = STUDY.replace('search = "on"\n', 'search = "off"\n').replace('name = "search"',
                                                                       'name = "pg"')
    text = text.replace(f"runs = {RUNS}", "runs = 2").replace(f"steps = {STEPS}", "steps = 6")
    out = tmp_path / "study"
    studies.run_study(parse_study(text), out, workers=1)
    g = pd.read_parquet(out / "gospa.parquet")
    assert g["undetected"].notna().all()              # the pmb tracker's count is stored
    now = write_report(out, tmp_path / "now")
    # The report as it was before the search section existed.
    monkeypatch.setattr(document, "search_section", lambda *a: None)
    monkeypatch.setattr(document, "draw_search_figures", lambda *a: {})
    before = write_report(out, tmp_path / "before")
    assert now.markdown.read_text() == before.markdown.read_text()
    assert set(now.figures) == set(before.figures)
    assert "undetected" not in now.markdown.read_text().lower()
    assert not list((tmp_path / "now").glob("undetected*.png"))
