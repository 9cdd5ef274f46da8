"""Documented command outputs: find them, run them, compare them, rewrite them.

A documented output is a fenced block in README.md or docs/*.md whose first line is a
command (``$ sensorplan ...``; a line ending in ``\\`` continues on the next), followed by
what the command prints. An HTML comment on the line before the block says what it is:

``<!-- output: checked -->``
    ``tests/cli/test_documented_outputs.py`` runs the block's commands and compares what they
    print with the block; this script rewrites the block with what they print now.
``<!-- output: measured YYYY-MM-DD; not checked: REASON -->``
    an output too slow, too machine-dependent or needing set-up the test cannot give (a
    timing benchmark, a read-only install, a study of minutes): measured on that date with
    the command shown, and left out of the test for REASON.

Options of a checked block, after ``checked`` and separated by ``;``:

``times: REGEX``
    numbers inside REGEX's groups are times (or other wall-clock figures): any value is
    accepted there, and everything else on the line still counts. May be given more than
    once.
``given: FILE``
    FILE is an input the block shows with ``$ cat FILE``: it is written from that output
    before the commands run.
``needs: MODULE``
    the commands import an optional dependency (``stonesoup``): the test skips the block,
    with that reason, where it is not installed.

How a block runs. All its commands run in one ``bash``, in order, in an empty temporary
directory that links the repository's ``examples``, ``configs`` and ``studies``, with
``sensorplan`` and ``python`` meaning this checkout's (``python -m sensorplan`` with
``PYTHONPATH`` at ``src``), stdout and stderr together as a terminal shows them (unbuffered),
``COLUMNS=80`` and no colour. ``echo $?`` sees the previous command's status.

How outputs compare (the test and this script use the same rules):

- lines are compared after stripping, with runs of spaces and of the table-drawing
  characters ``━─═`` collapsed (a wider number widens a table column);
- the one-off notes of a first run that compiles the numerical kernels (``note: first run:
  ...``, ``note: first plan: ...``) and progress lines (``...: 12/120 done, 5 s elapsed,
  ...``) are not part of the output: they depend on the machine's state;
- a number with a decimal point agrees when it is within one unit of its last shown digit
  (a rounding flip) or 1e-9 relative; an integer must be equal; numbers marked as times
  (``times:``) may differ;
- a documented line ``...`` (alone, or followed by a space and a comment) stands for any
  number of lines; ``...`` inside a line stands for any text, and such a line's numbers
  must then match as written.

Usage::

    python scripts/refresh_doc_outputs.py                 # every checked block
    python scripts/refresh_doc_outputs.py docs/cli.md     # the blocks of some files
    python scripts/refresh_doc_outputs.py --check         # compare only; exit 1 on a stale one

When a block's text no longer lines up with the output (its wording changed, not just its
numbers), the whole output is written and the script says so: cut it again by hand where the
block elided lines with ``...``.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The files whose blocks are documented outputs.
DOC_FILES = ("README.md", "docs")
#: Folders of the repository the commands may read (linked into the run directory).
LINKED = ("examples", "configs", "studies")
#: Longest a block may run (s).
TIMEOUT = 300

MARKER = re.compile(r"^<!--\s*output:\s*(?P<body>.*?)\s*-->\s*$")
MEASURED = re.compile(r"^measured (?P<date>\d{4}-\d{2}-\d{2}); not checked: (?P<reason>\S.*)$")
FENCE = re.compile(r"^(```+)")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: Lines that are no part of a command's output: first-run compile notes, progress.
IGNORED = (re.compile(r"^note: first (run|plan): "),
           re.compile(r"^[^:]+: \d+/\d+ .*\bdone\b.*\belapsed\b"))
#: A documented line standing for any number of lines.
WILDCARD = re.compile(r"^\.\.\.(\s|$)")
SPACES = re.compile(r"\s+")
RULES = re.compile(r"([━─═])\1+")


@dataclass
class Command:
    text: str                     # as shown, continuation lines joined with newlines
    expected: list[str]           # the documented output lines


@dataclass
class Block:
    path: Path
    line: int                     # 1-based line of the block's first command
    start: int                    # 0-based index of the first line inside the fence
    end: int                      # 0-based index of the closing fence
    lines: list[str]              # the lines inside the fence
    marker: str | None            # the marker's body, None when unmarked
    options: dict[str, list[str]] = field(default_factory=dict)

    @property
    def name(self) -> str:
        path = self.path.relative_to(ROOT) if self.path.is_relative_to(ROOT) else self.path
        return f"{path}:{self.line}"

    @property
    def checked(self) -> bool:
        return self.marker is not None and self.marker.split(";")[0].strip() == "checked"

    @property
    def commands(self) -> list[Command]:
        return split_commands(self.lines)

    @property
    def shows_output(self) -> bool:
        return any(c.expected for c in self.commands)


def split_commands(lines: Sequence[str]) -> list[Command]:
    """The commands of a block (``$ ...`` lines, ``\\`` continuing) and their outputs."""
    out: list[Command] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("$ "):
            parts = [line[2:]]
            while parts[-1].rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                parts.append(lines[i])
            out.append(Command("\n".join(parts), []))
        elif out:
            out[-1].expected.append(line)
        i += 1
    return out


def doc_files() -> list[Path]:
    files: list[Path] = []
    for name in DOC_FILES:
        p = ROOT / name
        files.extend(sorted(p.glob("*.md")) if p.is_dir() else [p])
    return files


def blocks(path: Path) -> Iterator[Block]:
    """The fenced blocks of ``path`` that start with a command, with their markers."""
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not lines[j].startswith(m.group(1)):
            j += 1
        inner = lines[i + 1:j]
        if inner and inner[0].startswith("$ "):
            k = i - 1
            while k >= 0 and not lines[k].strip():
                k -= 1
            mm = MARKER.match(lines[k]) if k >= 0 else None
            marker = mm.group("body") if mm else None
            block = Block(path, i + 2, i + 1, j, inner, marker)
            if marker is not None:
                for part in marker.split(";")[1:]:
                    key, _, value = part.strip().partition(":")
                    block.options.setdefault(key.strip(), []).append(value.strip())
            yield block
        i = j + 1


def all_blocks(files: Sequence[Path] | None = None) -> list[Block]:
    return [b for f in (files or doc_files()) for b in blocks(f)]


def markers_without_block(path: Path) -> list[int]:
    """Lines of markers that are not followed by a command block (a mistake)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    owned = {b.start - 1 for b in blocks(path)}
    bad = []
    for i, line in enumerate(lines):
        if MARKER.match(line):
            k = i + 1
            while k < len(lines) and not lines[k].strip():
                k += 1
            if k not in owned:
                bad.append(i + 1)
    return bad


def marker_problem(block: Block) -> str | None:
    """What is wrong with a block's marker, or None."""
    if block.marker is None:
        return "shows a command's output but has no marker" if block.shows_output else None
    if block.checked:
        for key, values in block.options.items():
            if key not in ("times", "given", "needs"):
                return f"unknown option {key!r} (times, given, needs)"
            if key == "times":
                for v in values:
                    try:
                        if re.compile(v).groups == 0:
                            return f"times regex {v!r} has no group"
                    except re.error as exc:
                        return f"times regex {v!r}: {exc}"
        return None
    if not MEASURED.match(block.marker):
        return ("marker must be 'checked' or 'measured YYYY-MM-DD; not checked: REASON', "
                f"got {block.marker!r}")
    return None


# ------------------------------------------------------------------------------- running


def _environment(bin_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}",
               PYTHONPATH=os.pathsep.join([str(ROOT / "src")]
                                          + ([env["PYTHONPATH"]] if env.get("PYTHONPATH")
                                             else [])),
               PYTHONUNBUFFERED="1", COLUMNS="80", LINES="40", NO_COLOR="1", TERM="dumb")
    env.pop("FORCE_COLOR", None)
    return env


def run_block(block: Block) -> list[list[str]]:
    """Run a block's commands; the output lines of each (ignored lines removed)."""
    commands = block.commands
    with tempfile.TemporaryDirectory(prefix="doc-output-") as tmp:
        work, bin_dir = Path(tmp) / "work", Path(tmp) / "bin"
        work.mkdir()
        bin_dir.mkdir()
        for name in LINKED:
            (work / name).symlink_to(ROOT / name, target_is_directory=True)
        for name, text in (("sensorplan", f'exec "{sys.executable}" -m sensorplan "$@"'),
                           ("python", f'exec "{sys.executable}" "$@"')):
            (bin_dir / name).write_text(f"#!/bin/sh\n{text}\n")
            (bin_dir / name).chmod(0o755)
        for given in block.options.get("given", []):
            shown = next((c.expected for c in commands if c.text.strip() == f"cat {given}"),
                         None)
            if shown is None:
                raise ValueError(f"{block.name}: given {given!r} but no '$ cat {given}'")
            (work / given).write_text("\n".join(shown) + "\n")
        script = ["__s=0"]
        for k, c in enumerate(commands):
            script += [f"printf '\\n@@doc-output {k}@@\\n'", "(exit $__s)",
                       "{ " + c.text, "} 2>&1; __s=$?"]
        proc = subprocess.run(["bash", "-c", "\n".join(script)], cwd=work,
                              env=_environment(bin_dir), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=TIMEOUT)
    outputs: list[list[str]] = [[] for _ in commands]
    k = -1
    for line in proc.stdout.splitlines():
        m = re.fullmatch(r"@@doc-output (\d+)@@", line)
        if m:
            k = int(m.group(1))
            continue
        if k >= 0 and not any(p.search(line) for p in IGNORED):
            outputs[k].append(line.rstrip())
    for out in outputs:
        while out and not out[-1].strip():
            out.pop()
    return outputs


# ----------------------------------------------------------------------------- comparing


def normalise(line: str) -> str:
    return RULES.sub(r"\1", SPACES.sub(" ", line.strip()))


def _time_spans(line: str, times: Sequence[str]) -> list[tuple[int, int]]:
    spans = []
    for pattern in times:
        for m in re.finditer(pattern, line):
            spans += [m.span(g) for g in range(1, (m.lastindex or 0) + 1) if m.start(g) >= 0]
    return spans


def _tokens(line: str, times: Sequence[str]) -> list[tuple[str, str | None, bool]]:
    """``(kind, text, is_time)``: text pieces and numbers of a normalised line."""
    spans = _time_spans(line, times)
    out: list[tuple[str, str | None, bool]] = []
    pos = 0
    for m in NUMBER.finditer(line):
        if m.start() > pos:
            out.append(("text", line[pos:m.start()], False))
        is_time = any(a <= m.start() and m.end() <= b for a, b in spans)
        out.append(("number", m.group(), is_time))
        pos = m.end()
    if pos < len(line):
        out.append(("text", line[pos:], False))
    return out


def numbers_agree(documented: str, printed: str) -> bool:
    """The tolerance rule for one number (see the module docstring)."""
    try:
        d, p = float(documented), float(printed)
    except ValueError:
        return documented == printed
    if not any(ch in documented for ch in ".eE"):
        return d == p and any(ch in printed for ch in ".eE") is False
    mantissa, _, exponent = documented.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    unit = 10.0 ** (-decimals + (int(exponent) if exponent else 0))
    return math.isfinite(p) and abs(p - d) <= unit * (1 + 1e-9) + 1e-9 * abs(d)


def line_matches(documented: str, printed: str, times: Sequence[str] = (),
                 structure_only: bool = False) -> bool:
    """Whether a printed line matches a documented one (``structure_only``: numbers may
    differ anywhere, for lining a block up with new output)."""
    d, p = normalise(documented), normalise(printed)
    if "..." in d:
        pattern = ".*".join(
            NUMBER.sub(lambda m: NUMBER.pattern, re.escape(part)) if structure_only
            else re.escape(part) for part in d.split("..."))
        return re.fullmatch(pattern, p) is not None
    td, tp = _tokens(d, times), _tokens(p, times)
    if len(td) != len(tp):
        return False
    for (kd, xd, time_d), (kp, xp, time_p) in zip(td, tp):
        if kd != kp:
            return False
        if kd == "text":
            if xd != xp:
                return False
        elif not (structure_only or time_d or time_p or numbers_agree(xd or "", xp or "")):
            return False
    return True


def align(documented: Sequence[str], printed: Sequence[str], times: Sequence[str] = (),
          structure_only: bool = False) -> list[int | None] | None:
    """For each documented line the index of the printed line it matches (None for a
    wildcard line), or None when the block does not match."""

    @cache
    def go(i: int, j: int) -> tuple[int | None, ...] | None:
        if i == len(documented):
            return () if j == len(printed) else None
        if WILDCARD.match(documented[i].strip()):
            for k in range(j, len(printed) + 1):
                rest = go(i + 1, k)
                if rest is not None:
                    return (None, *rest)
            return None
        if j < len(printed) and line_matches(documented[i], printed[j], times, structure_only):
            rest = go(i + 1, j + 1)
            if rest is not None:
                return (j, *rest)
        return None

    found = go(0, 0)
    return None if found is None else list(found)


def first_difference(documented: Sequence[str], printed: Sequence[str],
                     times: Sequence[str]) -> str:
    """A short description of where a documented output and a printed one part."""
    where = align(documented, printed, times, structure_only=True)
    if where is not None:                 # the same lines: some number differs
        for line, j in zip(documented, where):
            if j is not None and not line_matches(line, printed[j], times):
                return (f"documented {line.strip()!r}, but the command printed "
                        f"{printed[j].strip()!r}")
    j = 0
    for i, line in enumerate(documented):
        if WILDCARD.match(line.strip()):
            return "the lines around a '...' do not match"
        if j >= len(printed):
            return f"documented line {i + 1} {line.strip()!r}: the command printed nothing more"
        if not line_matches(line, printed[j], times):
            return (f"documented line {i + 1} {line.strip()!r}, but the command printed "
                    f"{printed[j].strip()!r}")
        j += 1
    return f"the command printed more: {printed[j].strip()!r}" if j < len(printed) else ""


def compare(block: Block, outputs: Sequence[Sequence[str]]) -> list[str]:
    """Problems of a checked block against the outputs of its commands."""
    times = block.options.get("times", [])
    problems = []
    for c, printed in zip(block.commands, outputs):
        if align(c.expected, printed, times) is None:
            problems.append(f"$ {c.text}: {first_difference(c.expected, printed, times)}")
    return problems


# ------------------------------------------------------------------------------ rewriting


def refreshed_lines(block: Block, outputs: Sequence[Sequence[str]]) -> tuple[list[str], bool]:
    """The block's new inner lines, and whether every command's output lined up."""
    times = block.options.get("times", [])
    new: list[str] = []
    lined_up = True
    for c, printed in zip(block.commands, outputs):
        new += ["$ " + c.text.split("\n")[0], *c.text.split("\n")[1:]]
        where = align(c.expected, printed, times, structure_only=True)
        if where is None:
            lined_up = False
            new += list(printed)
            continue
        for documented, j in zip(c.expected, where):
            if j is None or "..." in documented:
                new.append(documented)
            else:
                new.append(printed[j])
    return new, lined_up


def refresh(path: Path, check_only: bool = False) -> tuple[int, int]:
    """Rewrite (or only compare) the checked blocks of ``path``; (blocks, stale ones)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found = [b for b in blocks(path) if b.checked]
    stale = 0
    for block in reversed(found):                     # from the end: indices stay valid
        outputs = run_block(block)
        problems = compare(block, outputs)
        if not problems:
            print(f"{block.name}: up to date")
            continue
        stale += 1
        for p in problems:
            print(f"{block.name}: {p}")
        if check_only:
            continue
        new, lined_up = refreshed_lines(block, outputs)
        lines[block.start:block.end] = new
        print(f"{block.name}: rewritten" + ("" if lined_up else
              " with the whole output (its text changed): cut it again where it elided "
              "lines with '...'"))
    if stale and not check_only:
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    for b in blocks(path):
        if b.marker is not None and not b.checked:
            print(f"{b.name}: not checked ({b.marker})")
    return len(found), stale


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("files", nargs="*", type=Path,
                        help="markdown files (default: README.md and docs/*.md)")
    parser.add_argument("--check", action="store_true",
                        help="only compare; exit status 1 when a block is stale")
    args = parser.parse_args(argv)
    files = [f.resolve() for f in args.files] or doc_files()
    total = stale = 0
    for f in files:
        for b in blocks(f):
            problem = marker_problem(b)
            if problem:
                print(f"{b.name}: {problem}")
        n, s = refresh(f, args.check)
        total, stale = total + n, stale + s
    print(f"{total} checked blocks, {stale} {'stale' if args.check else 'rewritten'}")
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
