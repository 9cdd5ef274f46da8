"""Documented outputs are what the documented commands print.

Every fenced block of README.md and docs/*.md that starts with a command (``$ ...``) and
shows its output carries a marker: ``<!-- output: checked -->`` blocks are run here and
compared with their text (rules in ``scripts/refresh_doc_outputs.py``, which rewrites them:
``python scripts/refresh_doc_outputs.py``); ``<!-- output: measured DATE; not checked:
REASON -->`` blocks are left out, each with its date and reason.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("refresh_doc_outputs",
                                               ROOT / "scripts" / "refresh_doc_outputs.py")
assert _spec is not None and _spec.loader is not None
docs = importlib.util.module_from_spec(_spec)
sys.modules["refresh_doc_outputs"] = docs
_spec.loader.exec_module(docs)

BLOCKS = docs.all_blocks()
CHECKED = [b for b in BLOCKS if b.checked]
HINT = "run `python scripts/refresh_doc_outputs.py` to rewrite it from the command's output"


def test_every_documented_output_is_marked_and_every_marker_is_well_formed() -> None:
    problems = [f"{b.name}: {p}" for b in BLOCKS if (p := docs.marker_problem(b))]
    problems += [f"{f.relative_to(ROOT)}:{line}: marker without a command block after it"
                 for f in docs.doc_files() for line in docs.markers_without_block(f)]
    assert not problems, "\n".join(problems)
    # The blocks this test knows: plan, errors, simulate, agents and the Stone Soup example
    # are checked; the timing benchmarks and the read-only install are not.
    assert len(CHECKED) >= 6
    assert {b.path.name for b in CHECKED} >= {"cli.md", "stonesoup.md"}


def test_excluded_outputs_say_when_they_were_measured_and_why() -> None:
    excluded = [b for b in BLOCKS if b.marker is not None and not b.checked]
    assert excluded
    for b in excluded:
        m = docs.MEASURED.match(b.marker)
        assert m and len(m.group("reason")) > 10, b.name


@pytest.mark.parametrize("block", CHECKED, ids=[b.name for b in CHECKED])
def test_documented_output_is_what_the_command_prints(block) -> None:
    for module in block.options.get("needs", []):
        pytest.importorskip(module, reason=f"{block.name} runs {module}, not installed")
    problems = docs.compare(block, docs.run_block(block))
    assert not problems, f"{block.name}: stale; {HINT}:\n" + "\n".join(problems)


# ------------------------------------------------------------------ the comparison rules


def test_numbers_agree_to_one_unit_of_their_last_digit_and_integers_exactly() -> None:
    assert docs.numbers_agree("5.2", "5.3") and docs.numbers_agree("5.2", "5.1")
    assert not docs.numbers_agree("5.2", "5.4")
    assert docs.numbers_agree("15.154891421337075", "15.154891421337071")
    assert not docs.numbers_agree("6.107857504313278", "15.154891421337075")
    assert docs.numbers_agree("120", "120") and not docs.numbers_agree("120", "121")
    assert not docs.numbers_agree("120", "120.0")
    assert docs.numbers_agree("1.5e-3", "1.6e-3") and not docs.numbers_agree("1.5e-3", "1.7e-3")


def test_times_may_differ_and_nothing_else_on_their_line() -> None:
    times = [r'"seconds": (\S+)']
    assert docs.line_matches('"seconds": 0.27491', '"seconds": 0.0024', times)
    assert not docs.line_matches('"seconds": 0.27491', '"seconds": 0.0024')
    assert not docs.line_matches('"potential": 6.1, "seconds": 0.27',
                                 '"potential": 9.1, "seconds": 0.27', times)
    # A wider number widens a table: spaces and rules collapse.
    assert docs.line_matches("│   17.23 │ 40.5 │", "│  117.23 │   40.5 │", [r"│ +(\S+) │"])
    assert docs.line_matches("┏━━━━┳━━┓", "┏━━━━━━┳━━┓")


def test_ellipses_stand_for_lines_and_for_text() -> None:
    documented = ["first", "...  (the tables)", "last 3"]
    assert docs.align(documented, ["first", "a", "b", "last 3"]) == [0, None, 3]
    assert docs.align(documented, ["first", "last 3"]) == [0, None, 1]
    assert docs.align(documented, ["first", "a", "last 4"]) is None
    assert docs.line_matches("choose from ...", "choose from a, b, c")
    assert not docs.line_matches("wrote out/x, .../episode.png", "wrote out/y/episode.png")


def test_a_stale_block_is_found_and_rewritten(tmp_path: Path) -> None:
    """What this test guards against: docs/cli.md once showed a potential of 6.11 where the
    same command printed 15.15."""
    page = tmp_path / "page.md"
    page.write_text("Text.\n\n<!-- output: checked; times: \"seconds\": (\\S+) -->\n"
                    "```console\n$ echo '{\"potential\": 6.1, \"seconds\": 0.5}'\n"
                    "{\"potential\": 6.1, \"seconds\": 0.5}\n$ echo done; false\ndone\n"
                    "$ echo $?\n0\n```\n")
    (block,) = docs.blocks(page)
    outputs = docs.run_block(block)
    assert outputs == [['{"potential": 6.1, "seconds": 0.5}'], ["done"], ["1"]]
    assert docs.compare(block, outputs) == ["$ echo $?: documented '0', but the command "
                                            "printed '1'"]
    page.write_text(page.read_text().replace("6.1, \"seconds\": 0.5}'", "9.9, \"seconds\": 7}'"))
    (block,) = docs.blocks(page)
    assert len(docs.compare(block, docs.run_block(block))) == 2
    docs.refresh(page)
    (block,) = docs.blocks(page)
    assert docs.compare(block, docs.run_block(block)) == []
    assert '{"potential": 9.9, "seconds": 7}\n$ echo done; false\ndone\n$ echo $?\n1\n' \
        in page.read_text()
