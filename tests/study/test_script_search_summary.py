"""scripts/search_summary.py against a direct computation from a tiny search study's tables:
the assigned track of a target-step read off the steps table's estimate (the recorder's
assignment) and matched to the tracks table, then counted target by target in plain Python."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sensorplan.errors import ConfigError
from sensorplan.study import load_study, run_study
from sensorplan.study.storage import load_study_dir
from script_helpers import script_module

ROOT = Path(__file__).resolve().parents[2]
STUDY = """
runs = 3
steps = 60
seed = 17
[scenario]
preset = "search"
[defaults]
search = "off"
[[methods]]
name = "myopic"
planner = "pg"
[[methods]]
name = "gnn"
planner = "pg"
[methods.tracker]
kind = "gnn"
"""


def _script():
    return script_module("search_summary")


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("search_summary")
    (base / "s.toml").write_text(STUDY)
    run_study(load_study(base / "s.toml"), base / "out", workers=1)
    return base / "out"


def _direct(study_dir: Path) -> pd.DataFrame:
    """Per (method, run, target): the metrics counted step by step."""
    steps = pd.read_parquet(study_dir / "steps.parquet")
    tracks = pd.read_parquet(study_dir / "tracks.parquet")
    known = {(m, r, t) for m, r, t in steps.loc[steps["step"] == 0,
                                                ["method", "run", "target"]].itertuples(
                                                    index=False)}
    s = steps[steps["step"] >= 1].merge(
        tracks.rename(columns={"x": "x_est", "y": "y_est"}),
        on=["run", "method", "step", "x_est", "y_est"], how="left")
    assert (s["label"].notna() == s["x_est"].notna()).all()   # every estimate is a track
    rows = []
    for (m, r, t), g in s.groupby(["method", "run", "target"]):
        g = g.sort_values("step")
        st, lab = g["step"].to_list(), g["label"].to_list()
        has = [not np.isnan(x) for x in lab]
        first = next((k for k, h in enumerate(has) if h), None)
        switches, prev = 0, None
        longest = cur = 0
        for k, h in enumerate(has):
            if h:
                switches += prev is not None and lab[k] != prev
                prev = lab[k]
            cur = 0 if h or (k and st[k] != st[k - 1] + 1) else cur
            cur += not h
            longest = max(longest, cur)
        rows.append(dict(
            method=m, run=r, target=t, known=(m, r, t) in known, live=len(st),
            first=-1 if first is None else st[first],
            delay=np.nan if first is None else st[first] - st[0], switches=switches,
            lost=longest >= 20,
            before=len(st) if first is None else first - sum(has[:first]),
            after=0 if first is None else sum(not h for h in has[first:])))
    return pd.DataFrame(rows)


def test_per_target_and_per_run_match_a_direct_count(study_dir: Path) -> None:
    script = _script()
    tables = load_study_dir(study_dir)
    got = script.per_target(tables).set_index(["method", "run", "target"]).sort_index()
    want = _direct(study_dir).set_index(["method", "run", "target"]).sort_index()
    assert got.index.equals(want.index)
    assert (~want["known"]).any() and (want["first"] < 0).any() and (want["first"] > 0).any()
    for col in ("known", "live", "first", "switches", "lost", "before", "after"):
        np.testing.assert_array_equal(got[col].to_numpy(), want[col].to_numpy(), err_msg=col)
    np.testing.assert_array_equal(got["delay"].to_numpy(), want["delay"].to_numpy())

    runs = script.per_run(tables, script.per_target(tables)).set_index(["method", "run"])
    g = pd.read_parquet(study_dir / "gospa.parquet")
    for (m, r), x in g.groupby(["method", "run"]):
        row, w = runs.loc[(m, r)], want.loc[(m, r)]
        assert row["gospa"] == pytest.approx(x["gospa"].mean(), rel=1e-12)
        # each missed target costs c^2/2 = 1250 m^2: the three parts add up to the gospa
        # table's missed count
        assert row["missed_share"] == pytest.approx(
            100 * x["missed"].sum() / 1250 / x["targets"].sum(), rel=1e-9)
        never = w["first"] < 0
        assert row["missed_never"] == pytest.approx(100 * w.loc[never, "live"].sum()
                                                    / w["live"].sum(), rel=1e-12)
        assert row["switches"] == w["switches"].sum() and row["lost"] == w["lost"].sum()
        born = ~w["known"]
        assert row["born"] == born.sum()
        if born.any():
            assert row["found_born"] == pytest.approx(100 * (born & ~never).sum() / born.sum())


def test_the_latency_line_is_the_pooled_distribution(study_dir: Path) -> None:
    want = _direct(study_dir)
    text = "\n".join(_script().summary_lines(load_study_dir(study_dir), "myopic"))
    t = want[(want["method"] == "gnn") & ~want["known"]]
    d = t["delay"].dropna().to_numpy(float)
    never = int((t["first"] < 0).sum())
    assert (f"| gnn | born: {len(t)} | {np.median(d):.0f}; {np.percentile(d, 90):.0f}; "
            f"{d.max():.0f} | {never} ({100 * never / len(t):.1f} %) |") in text
    assert "Paired differences against myopic" in text


def test_a_study_split_into_parts_joins_to_the_whole(study_dir: Path, tmp_path: Path) -> None:
    """The same methods run as two study files with the same seed give, joined, the tables
    and summary of the one file: runs stay paired across the files."""
    head, tail = STUDY.split("[[methods]]\nname = \"gnn\"")
    (tmp_path / "a.toml").write_text(head)
    (tmp_path / "b.toml").write_text(head.split("[[methods]]")[0] + "[[methods]]\nname = \"gnn\""
                                     + tail)
    for part in ("a", "b"):
        run_study(load_study(tmp_path / f"{part}.toml"), tmp_path / part, workers=1)
    script = _script()
    joined = script.join([load_study_dir(tmp_path / "a"), load_study_dir(tmp_path / "b")])
    whole = load_study_dir(study_dir)
    assert joined.study.method_names == whole.study.method_names == ["myopic", "gnn"]
    keys = ["method", "run", "step"]
    for name in ("gospa", "tracks"):
        got = getattr(joined, name).sort_values(keys + (["label"] if name == "tracks" else []))
        want = getattr(whole, name).sort_values(keys + (["label"] if name == "tracks" else []))
        # the recorded intensity (arrays, or nothing for a tracker without one) is compared
        # apart: concatenation may store "nothing" as NaN rather than None
        a, b = (f.reset_index(drop=True) for f in (got, want))
        if "intensity" in a:
            def missing(v: object) -> bool:
                return v is None or (isinstance(v, float) and np.isnan(v))

            for x, y in zip(a.pop("intensity"), b.pop("intensity")):
                assert missing(x) == missing(y)
                if not missing(x):
                    np.testing.assert_array_equal(x, y)
        pd.testing.assert_frame_equal(a, b, check_categorical=False)
    assert script.summary_lines(joined, "myopic") == script.summary_lines(whole, "myopic")


def test_parts_of_different_studies_are_refused(study_dir: Path, tmp_path: Path) -> None:
    (tmp_path / "c.toml").write_text(STUDY.replace("seed = 17", "seed = 18").split(
        "[[methods]]\nname = \"gnn\"")[0].replace('name = "myopic"', 'name = "other"'))
    run_study(load_study(tmp_path / "c.toml"), tmp_path / "c", workers=1)
    with pytest.raises(ConfigError, match="differ in seed"):
        _script().join([load_study_dir(study_dir), load_study_dir(tmp_path / "c")])
    with pytest.raises(ConfigError, match="duplicate method name"):
        _script().join([load_study_dir(study_dir), load_study_dir(study_dir)])


def test_another_scenario_joins_only_when_asked_and_repeated_names_are_renamed(
        study_dir: Path, capsys) -> None:
    import dataclasses

    script = _script()
    whole = load_study_dir(study_dir)
    other = dataclasses.replace(whole, study=dataclasses.replace(
        whole.study, scenario=dataclasses.replace(whole.study.scenario, process_noise=0.5)))
    renamed = script.renamed(other, "b", {"myopic", "gnn"})
    with pytest.raises(ConfigError, match="differ in scenario"):
        script.join([whole, renamed])
    joined = script.join([whole, renamed], other_scenario=True)
    assert joined.study.method_names == ["myopic", "gnn", "myopic@b", "gnn@b"]
    # The same runs under two names: paired against myopic, myopic@out differs by 0 and
    # gnn@out as gnn does.
    script.main([str(study_dir), "--with", str(study_dir), "--other-scenario",
                 "--reference", "myopic"])
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("| mean GOSPA (m) |")
               and "+" in line)
    gnn, myopic_again, gnn_again = row.strip("| ").split(" | ")[1:]
    assert myopic_again.startswith("+0.0 [+0.0, +0.0]") and gnn_again == gnn


def _mean_gospa_direct(study_dir: Path) -> dict[str, float]:
    """Per method: the mean over runs of each run's mean GOSPA, in plain Python."""
    g = pd.read_parquet(study_dir / "gospa.parquet")
    per_run: dict[str, list[float]] = {}
    for (m, _r), x in g.groupby(["method", "run"]):
        values = x["gospa"].to_list()
        per_run.setdefault(str(m), []).append(sum(values) / len(values))
    return {m: sum(v) / len(v) for m, v in per_run.items()}


def test_best_of_takes_the_lowest_mean_gospa_among_the_prefixed_methods(
        study_dir: Path) -> None:
    script = _script()
    tables = load_study_dir(study_dir)
    want = _mean_gospa_direct(study_dir)
    best, means = script.best_of(tables, "")
    assert set(means) == {"myopic", "gnn"}
    for m, v in want.items():
        assert means[m] == pytest.approx(v, rel=1e-12)
    assert best == min(want, key=want.__getitem__)
    # a prefix narrows the candidates, even to one that is not the lowest overall
    for name in ("myopic", "gnn"):
        assert script.best_of(tables, name[:2]) == (name, {name: means[name]})
    with pytest.raises(ValueError, match="starts with 'raster/'"):
        script.best_of(tables, "raster/")


def test_best_of_on_the_command_line_names_its_choice_and_takes_it_as_reference(
        study_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    script = _script()
    want = _mean_gospa_direct(study_dir)
    best = min(want, key=want.__getitem__)
    other = next(m for m in want if m != best)
    script.main([str(study_dir), "--best-of", ""])
    text = capsys.readouterr().out
    lo, hi = min(want.values()), max(want.values())
    assert text.startswith(f"Reference: {best}, the lowest mean GOSPA ({want[best]:.2f} m) "
                           f"of the 2 methods named ... (their means {lo:.2f}-{hi:.2f} m)")
    assert f"Paired differences against {best} per run" in text
    assert (f"| mean GOSPA ratio (method / {best}) | {want[other] / want[best]:.3f} |"
            in text)
    with pytest.raises(SystemExit) as exit_info:
        script.main([str(study_dir), "--best-of", "raster/"])
    assert exit_info.value.code == 2
    assert "no method's name starts with 'raster/'" in capsys.readouterr().err


def test_the_ratio_row_is_the_ratio_of_the_mean_gospas(study_dir: Path) -> None:
    want = _mean_gospa_direct(study_dir)
    text = "\n".join(_script().summary_lines(load_study_dir(study_dir), "myopic"))
    assert f"| mean GOSPA ratio (method / myopic) | {want['gnn'] / want['myopic']:.3f} |" \
        in text
