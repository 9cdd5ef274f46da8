"""``--help`` reads at 80 columns, shows no value for a flag, and docs/cli.md describes
every option of every command.

The line budget at 80 columns, per command:

- the usage line and the description before the options fit in 20 lines, so that a
  24-line terminal shows them whole with the prompt;
- an option (or argument) takes at most 4 lines, and 3 on average: its names, a sentence
  of a few words and its default fit in 2-3 lines of the help column (35-45 characters
  wide); the fourth is for the lists of names, and an option that lists the nine built-in
  planners may take a fifth;
- no line is wider than 80 characters.

Before the options were grouped and shortened, ``simulate --help`` took 176 lines (options
of up to 10 lines in a 23-character column) and ``agents --help`` 225.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cli_helpers import run
from sensorplan.cli.app import cli_command

ROOT = Path(__file__).resolve().parents[2]
COMMAND = cli_command()
COMMANDS = ["", *COMMAND.commands]          # "" is sensorplan itself

#: The budget (see the module docstring).
HEAD_LINES, ENTRY_LINES, MEAN_ENTRY_LINES, WIDTH = 20, 4, 3.0, 80
#: The budget of an option whose help lists the built-in planners.
PLANNER_LIST_LINES = 5


def help_at_80(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
               command: str) -> list[str]:
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.delenv("TERMINAL_WIDTH", raising=False)
    code, out, err = run(capsys, *([command] if command else []), "--help")
    assert code == 0 and err == "", err
    return out.splitlines()


def entries(lines: list[str]) -> list[list[str]]:
    """The options, arguments or commands of a help text: the lines of each, in panels."""
    rows: list[list[str]] = []
    for line in lines:
        if not line.startswith("│"):
            continue
        if line[1:8].strip():                  # a name (or the required mark) starts a row
            rows.append([line])
        elif rows:
            rows[-1].append(line)
    return rows


@pytest.mark.parametrize("command", COMMANDS)
def test_help_fits_its_budget_at_80_columns(command: str, capsys, monkeypatch) -> None:
    lines = help_at_80(capsys, monkeypatch, command)
    assert max(len(line) for line in lines) <= WIDTH
    head = next(i for i, line in enumerate(lines) if line.startswith("╭"))
    assert head <= HEAD_LINES, "\n".join(lines[:head])
    rows = entries(lines)
    sizes = [len(r) for r in rows]
    for row in rows:
        lists_planners = "sequential-greedy" in " ".join(row)
        assert len(row) <= (PLANNER_LIST_LINES if lists_planners else ENTRY_LINES), \
            "\n".join(row)
    assert sum(sizes) / len(sizes) <= MEAN_ENTRY_LINES


def _flags(command: str) -> list:
    cmd = COMMAND.commands[command] if command else COMMAND
    return [p for p in cmd.params if getattr(p, "is_flag", False)]


@pytest.mark.parametrize("command", COMMANDS)
def test_no_flag_shows_a_value(command: str, capsys, monkeypatch) -> None:
    text = "\n".join(help_at_80(capsys, monkeypatch, command))
    assert "<bool>" not in text and "VALUE" not in text
    flags = _flags(command) + [None]                   # None: --help
    for flag in flags:
        names = ["--help", "-h"] if flag is None else [*flag.opts, *flag.secondary_opts]
        helped = "Show this message and exit." if flag is None else flag.help
        row = next(ln for ln in text.splitlines()
                   if re.match(rf"│\s+(\*\s+)?{re.escape(names[0])}\s", ln))
        rest = row[1:]
        for name in names:
            rest = re.sub(rf"(?<![\w-]){re.escape(name)}(?![\w-])", "", rest, count=1)
        # Right after the names comes the help text, not a placeholder for a value.
        assert rest.split()[0] == helped.split()[0], row


def test_the_commands_have_flags_to_check() -> None:
    # The premise of the test above: it checks the flags there are.
    assert {"--version"} <= {o for p in _flags("") for o in p.opts}
    assert {"--gate", "--known-map", "--reacquire", "--animate"} <= {
        o for p in _flags("simulate") for o in p.opts}


def test_docs_cli_describes_every_option_of_every_command() -> None:
    doc = (ROOT / "docs" / "cli.md").read_text()
    missing = []
    for name in COMMANDS:
        cmd = COMMAND.commands[name] if name else COMMAND
        for param in cmd.params:
            for opt in [*param.opts, *param.secondary_opts]:
                if opt.startswith("-") and not re.search(
                        rf"(?<![\w-]){re.escape(opt)}(?![\w-])", doc):
                    missing.append(f"{name or 'sensorplan'} {opt}")
    assert missing == []


def test_every_run_setting_option_has_a_row_in_the_docs_table() -> None:
    from sensorplan.simulation.settings import all_settings

    doc = (ROOT / "docs" / "cli.md").read_text()
    table = doc[doc.index("### Run-setting options"):]
    table = table[:table.index("\n### ")]
    rows = [ln for ln in table.splitlines() if ln.startswith("| `-")]
    declared = [(path, s) for _, path, _, s in all_settings() if s.cli]
    assert len(rows) == len(declared)
    for (path, s), row in zip(declared, rows):
        assert row.startswith(f"| `{s.cli[0].split('/')[0]}") and f"| `{path}` |" in row
