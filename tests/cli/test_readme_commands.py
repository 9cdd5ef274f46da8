"""The README's commands say what they cost when it is more than seconds."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_study_in_the_readme_says_its_size_and_time() -> None:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## Using it\n\n```bash\n(.*?)```", text, re.S).group(1)
    lines = block.splitlines()
    studies = [i for i, ln in enumerate(lines) if " study " in ln]
    assert studies, "the README shows a study"
    for i in studies:
        path = re.search(r"study (\S+\.toml)", lines[i]).group(1)
        data = tomllib.loads((ROOT / path).read_text())
        # Its comment: the line itself and the comment-only lines under it.
        comment = lines[i].partition("#")[2]
        for ln in lines[i + 1:]:
            if not ln.strip().startswith("#"):
                break
            comment += " " + ln.strip().lstrip("#")
        size = f"{data['runs']} runs x {len(data['methods'])} methods"
        assert size in comment, (lines[i], comment)
        assert re.search(r"\d+ (s|min)\b", comment), comment
