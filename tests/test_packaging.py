"""The package's metadata in the form setuptools keeps building (PEP 639)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_license_is_an_spdx_expression_with_its_file() -> None:
    # The table form (license = { text = "MIT" }) is deprecated by setuptools, which stops
    # building it after 2027-02-18.
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = data["project"]
    assert project["license"] == "MIT"
    assert project["license-files"] == ["LICENSE"]
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
    # setuptools reads both only from version 77 on.
    setuptools = next(r for r in data["build-system"]["requires"] if r.startswith("setuptools"))
    assert int(re.fullmatch(r"setuptools>=(\d+).*", setuptools).group(1)) >= 77
