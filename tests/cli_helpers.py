"""Helpers shared by the command-line tests: the documented decision example and running the CLI."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import Any

import pytest

from sensorplan.cli.app import main

#: The documented decision example, verbatim (docs/cli.md).
SPEC7_TEXT = """
{
  "dt": 1.0, "steps_per_epoch": 1, "horizon": 3,
  "map": {"width": 600, "height": 600},
  "process_noise": 0.05, "visibility": "probabilistic", "objective": "terminal",
  "targets": [{"mean": [300, 200, 4, 1], "cov": [[400,0,0,0],[0,400,0,0],[0,0,4,0],[0,0,0,4]]}],
  "sensors": [{"position": [100, 100], "altitude": 500, "heading": 0.0,
               "moves": [20, 40], "max_turn": 0.785398,
               "fov_half_angle": 0.523599, "min_ground_range": 250, "max_ground_range": 450,
               "depression": 0.698132, "snr_ref_db": 15, "range_ref": 600,
               "beamwidth": 0.0523599, "monopulse_slope": 1.6, "range_resolution": 30}],
  "planner": {"name": "pg", "alpha": 0.3, "beta": 0.95, "max_inner": 50,
              "max_outer": 10, "seed": 0}
}
"""
SPEC7 = json.loads(SPEC7_TEXT)


def run(capsys: pytest.CaptureFixture[str], *args: Any) -> tuple[int, str, str]:
    """Run the console entry point; return (exit status, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return int(info.value.code or 0), out.out, out.err


def assert_bad_input(result: tuple[int, str, str], field: str) -> str:
    """Exit 2, nothing on stdout, one stderr line naming ``field``; returns that line."""
    code, out, err = result
    assert code == 2, err
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"error: {field}: "), lines[0]
    assert "Traceback" not in err
    return lines[0]


def set_path(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """A mutation of a parsed input file setting a dotted path such as
    ``sensors.0.altitude`` (digits index lists) to ``value``."""
    def mutate(d: dict[str, Any]) -> None:
        keys: list[Any] = [int(k) if k.isdigit() else k for k in path.split(".")]
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return mutate


#: A plain progress line of the command line (``simulate: 2/4 steps done, 6 s elapsed``).
PROGRESS_LINE = re.compile(r"^[\w -]+: \d+/\d+( \w+)? done")


def said(stderr: str) -> list[str]:
    """The lines of ``stderr`` other than progress lines: a run slowed by a loaded host
    prints its progress (stderr is a pipe), which says nothing about how it ended."""
    return [line for line in stderr.splitlines() if not PROGRESS_LINE.match(line)]
