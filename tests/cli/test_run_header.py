"""What a run's summary says: only the tracker settings that act, the planner named as the
plan file names it, and the files written as whole paths."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cli_helpers import SPEC7, run

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "configs" / "quick.toml"


def header(capsys, tmp_path: Path, *options: str) -> tuple[list[str], str]:
    """The two header lines of a 2-step run, joined as printed, and the whole output."""
    code, out, err = run(capsys, "simulate", QUICK, "--steps", "2", "--out", tmp_path / "o",
                         *options)
    assert code == 0, err
    lines = out.splitlines()
    end = next(i for i, ln in enumerate(lines) if "Position error" in ln)
    text = " ".join(ln.strip() for ln in lines[:end])
    first, _, second = text.partition(" visibility ")
    return [first, "visibility " + second], out


@pytest.mark.parametrize("options,shown,hidden", [
    ((), ["model imm", "IMM q's (0.05, 5.0)", "IMM switching", "gate probability 0.999"],
     [", q 1.0"]),
    (("--tracker-model", "cv", "--tracker-q", "2.5"), ["model cv", ", q 2.5"],
     ["IMM q's", "IMM switching"]),
    (("--no-gate", "--no-reacquire"), ["gate False", "re-acquire False"],
     ["gate probability"]),
])
def test_the_header_shows_only_the_tracker_settings_that_act(
        options, shown, hidden, tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    _, tracker = header(capsys, tmp_path, *options)[0]
    for words in shown:
        assert words in tracker, tracker
    for words in hidden:
        assert words not in tracker, tracker


def test_the_header_and_the_plan_file_name_a_plugin_alike(
        nearest_on_path: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    reference = "nearest_planner:NearestTargetPlanner"
    (first, _), _ = header(capsys, tmp_path, "--planner", reference)
    path = tmp_path / "p.json"
    path.write_text(json.dumps(SPEC7))
    code, out, err = run(capsys, "plan", path, "--planner", reference)
    assert code == 0, err
    name = json.loads(out)["planner"]
    assert name == "nearest"
    assert first.startswith(f"{name} ({reference}), K = 1,"), first
    (first, _), _ = header(capsys, tmp_path, "--planner", "pg")
    assert first.startswith("pg, K = 1,")                     # a built-in: its name only


def test_written_paths_are_whole_lines_at_80_columns(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    out_dir = tmp_path / ("a-directory-name-long-enough-that-its-files-pass-eighty-columns" * 2)
    code, out, err = run(capsys, "simulate", QUICK, "--steps", "2", "--out", out_dir)
    assert code == 0, err
    for name in ("episode.npz", "episode.png", "episode.timing.json"):
        assert f"wrote {out_dir / name}" in out.splitlines()
