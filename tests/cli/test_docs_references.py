"""What users read cites only documents they have.

The team's internal contract and its issue tracker are not shipped: the README, every file in
docs/, the sources (docstrings, comments, help and error texts), the examples, scripts,
configs and study files, and the ``--help`` of ``sensorplan`` and of every subcommand must
state a rule (or point to the doc section that states it), never cite "SPEC 4" or
"issue 7".
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer

from cli_helpers import run
from sensorplan.cli.app import app

ROOT = Path(__file__).resolve().parents[2]

#: ``SPEC`` as a word (``SPEC 4``, ``SPEC's``, ``SPEC.md``); case matters (``spec`` is an
#: ordinary word and variable name). ``issue 7``, ``issue #7``, ``issues 3``, in any case.
SPEC_WORD = re.compile(r"\bSPEC\b")
ISSUE_NUMBER = re.compile(r"\bissues?\s*#?\s*\d", re.IGNORECASE)

#: Folders (and single files) whose text users read.
SHIPPED = ("README.md", "docs", "src", "examples", "scripts", "benchmarks", "configs", "studies")
TEXT_SUFFIXES = {".md", ".py", ".toml", ".json", ".txt", ".rst", ".sh", ".html", ".css",
                 ".js", ".cfg", ".ini", ".yaml", ".yml", ""}


def internal_references(text: str) -> list[tuple[int, str]]:
    """``(line number, line)`` of every line citing the contract or an issue number.

    Whitespace (line breaks included) is folded first, so a citation wrapped over two lines
    is found too; it is reported at the line where it starts.
    """
    found = []
    starts = [0] + [m.end() for m in re.finditer("\n", text)]
    for pattern in (SPEC_WORD, ISSUE_NUMBER):
        for match in pattern.finditer(text):
            line = sum(1 for s in starts if s <= match.start())
            found.append((line, text.splitlines()[line - 1].strip()))
    return sorted(set(found))


def shipped_files() -> Iterator[Path]:
    for name in SHIPPED:
        path = ROOT / name
        if path.is_file():
            yield path
            continue
        for file in sorted(path.rglob("*")):
            if (file.is_file() and file.suffix in TEXT_SUFFIXES
                    and "__pycache__" not in file.parts):
                yield file


def test_the_detector_finds_citations_and_nothing_else() -> None:
    hits = internal_references(
        "a (SPEC 4) rule\nSPEC's tie rule\nsee SPEC.md\nissue 7\nthe issue #12 fix\n"
        "issues\n 3 and more\nspec = SensorSpec()\nno issue here\nSPECTRUM, INSPECT\n")
    assert [line for line, _ in hits] == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("path", list(shipped_files()),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_shipped_text_cites_no_internal_document(path: Path) -> None:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        pytest.skip("not text")
    hits = internal_references(text)
    assert not hits, "\n".join(f"{path.relative_to(ROOT)}:{n}: {line}" for n, line in hits)


def commands(command: Any, prefix: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    """The argument prefix of the program and of every (sub)command under it.

    Typer's groups are its own click's, so groups are told by their ``commands``.
    """
    yield prefix
    subcommands = getattr(command, "commands", {})
    for name in sorted(subcommands):
        yield from commands(subcommands[name], prefix + (name,))


def test_every_help_text_cites_no_internal_document(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "400")              # no wrapping inside a citation
    names = list(commands(typer.main.get_command(app)))
    assert ("plan",) in names and ("study",) in names and len(names) > 6, names
    for args in names:
        code, out, err = run(capsys, *args, "--help")
        assert code == 0 and "Usage" in out, (args, err)
        # Rich draws panels: drop the box characters so that a wrapped citation still reads.
        flat = re.sub(r"[\u2500-\u257f]", " ", out)
        hits = internal_references(flat)
        assert not hits, f"sensorplan {' '.join(args)} --help: {hits}"
