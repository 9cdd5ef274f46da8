"""Fuzzing the three input files through the command line (in-process ``main``).

Each case is a valid ``plan`` JSON, scenario TOML or study TOML document mutated by
:mod:`fuzz_docs` (types, NaN and infinities, extreme and huge numbers, over-long integer
literals, wrong shapes, repeated and unknown keys, hostile strings, deep nesting, degrees
for radians, truncation). The contract (:func:`fuzz_docs.check_outcome`): exit 2 with one
stderr line naming a field and nothing on stdout, or a valid result; never a traceback, an
internal error, a warning on stderr or a hang.

The default suite runs a few hundred derandomized cases (tiny horizons and runs); the
``slow`` tests run thousands with fresh random seeds.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

import fuzz_docs as fz
from sensorplan.cli.app import main

#: Longest a single case may take (s) before it counts as a hang.
CASE_SECONDS = 120


class CaseTimeout(BaseException):
    """A case ran past CASE_SECONDS (BaseException: the CLI's handler must not catch it)."""


@contextlib.contextmanager
def time_limit(seconds: int) -> Iterator[None]:
    def expire(signum: int, frame: object) -> None:
        raise CaseTimeout(f"no answer in {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run_cli(args: list[str]) -> fz.Outcome:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            time_limit(CASE_SECONDS):
        try:
            main(args)
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
    return fz.Outcome(code, out.getvalue(), err.getvalue())


@contextlib.contextmanager
def scratch() -> Iterator[Path]:
    d = Path(tempfile.mkdtemp(prefix="sensorplan-fuzz-"))
    try:
        yield d
    finally:
        shutil.rmtree(d, ignore_errors=True)


def _write(path: Path, text: str) -> None:
    # surrogateescape: a lone surrogate in the text is written as the bytes it stands for
    # (the file is then not UTF-8, which is bad input of its own).
    path.write_bytes(text.encode("utf-8", "surrogatepass"))


def plan_case(text: str, done: list[str]) -> None:
    with scratch() as d:
        f = d / "problem.json"
        _write(f, text)
        outcome = run_cli(["plan", str(f)])
    try:
        fz.check_outcome(outcome, "plan")
    except AssertionError as exc:
        raise AssertionError(f"mutations: {done}\n{exc}") from None


def scenario_case(text: str, done: list[str]) -> None:
    with scratch() as d:
        f = d / "scenario.toml"
        _write(f, text)
        outcome = run_cli(["simulate", str(f), "--out", str(d / "out")])
        if outcome.code == 0:
            assert (d / "out" / "episode.npz").exists() and (d / "out" / "episode.png").exists()
    try:
        fz.check_outcome(outcome, "simulate", ("simulating",))
    except AssertionError as exc:
        raise AssertionError(f"mutations: {done}\n{exc}") from None


def study_case(text: str, done: list[str]) -> None:
    with scratch() as d:
        f = d / "study.toml"
        _write(f, text)
        outcome = run_cli(["study", str(f), "--out", str(d / "out"), "--workers", "1"])
        if outcome.code == 0:
            assert (d / "out" / "steps.parquet").exists()
            outcome = fz.Outcome(0, "", outcome.err)          # stdout: the summary lines
    try:
        fz.check_outcome(outcome, "study", ("study ",))
    except AssertionError as exc:
        raise AssertionError(f"mutations: {done}\n{exc}") from None


FAST = settings(max_examples=200, derandomize=True, deadline=None, database=None,
                suppress_health_check=list(HealthCheck))


# ------------------------------------------------------------------- default suite


@FAST
@given(fz.document(fz.PLAN_DOC, json_doc=True))
def test_fuzz_plan(case: tuple[str, list[str]]) -> None:
    plan_case(*case)


@settings(FAST, max_examples=30)
@given(fz.document(fz.SCENARIO_DOC, json_doc=False))
def test_fuzz_scenario(case: tuple[str, list[str]]) -> None:
    scenario_case(*case)


@settings(FAST, max_examples=30)
@given(fz.document(fz.STUDY_DOC, json_doc=False))
def test_fuzz_study(case: tuple[str, list[str]]) -> None:
    study_case(*case)


@settings(FAST, max_examples=60)
@given(fz.extreme_plan())
def test_fuzz_valid_extreme_plans(doc: dict) -> None:
    # Every number inside its documented range, bounds often: a clean result or a
    # documented joint limit, never an internal error or a non-finite number.
    plan_case(fz.to_json(doc), ["every value at an extreme of its range"])


@settings(FAST, max_examples=12)
@given(fz.extreme_scenario())
def test_fuzz_valid_extreme_scenarios(doc: dict) -> None:
    scenario_case(fz.to_toml(doc), ["every value at an extreme of its range"])


def test_the_unmutated_documents_are_valid() -> None:
    # Otherwise every case would only test the first error of a bad base document.
    plan_case(fz.to_json(fz.PLAN_DOC), [])
    with scratch() as d:
        f = d / "problem.json"
        f.write_text(fz.to_json(fz.PLAN_DOC))
        assert run_cli(["plan", str(f)]).code == 0
        f = d / "s.toml"
        f.write_text(fz.to_toml(fz.SCENARIO_DOC))
        assert run_cli(["simulate", str(f), "--out", str(d / "o")]).code == 0
        f = d / "st.toml"
        f.write_text(fz.to_toml(fz.STUDY_DOC))
        assert run_cli(["study", str(f), "--out", str(d / "so"), "--workers", "1"]).code == 0


# ------------------------------------------------------------------------ slow runs

SLOW = settings(deadline=None, database=None, suppress_health_check=list(HealthCheck))


@pytest.mark.slow
@settings(SLOW, max_examples=3000)
@given(fz.document(fz.PLAN_DOC, json_doc=True))
def test_fuzz_plan_long(case: tuple[str, list[str]]) -> None:
    plan_case(*case)


@pytest.mark.slow
@settings(SLOW, max_examples=600)
@given(fz.document(fz.SCENARIO_DOC, json_doc=False))
def test_fuzz_scenario_long(case: tuple[str, list[str]]) -> None:
    scenario_case(*case)


@pytest.mark.slow
@settings(SLOW, max_examples=400)
@given(fz.document(fz.STUDY_DOC, json_doc=False))
def test_fuzz_study_long(case: tuple[str, list[str]]) -> None:
    study_case(*case)


@pytest.mark.slow
@settings(SLOW, max_examples=3000)
@given(fz.extreme_plan())
def test_fuzz_valid_extreme_plans_long(doc: dict) -> None:
    plan_case(fz.to_json(doc), ["every value at an extreme of its range"])


@pytest.mark.slow
@settings(SLOW, max_examples=600)
@given(fz.extreme_scenario())
def test_fuzz_valid_extreme_scenarios_long(doc: dict) -> None:
    scenario_case(fz.to_toml(doc), ["every value at an extreme of its range"])


def _with_planner(name: str) -> dict:
    doc = dict(fz.PLAN_DOC)
    doc["planner"] = {"name": name, "seed": 1}
    return doc


@pytest.mark.slow
@pytest.mark.parametrize("name", ["random", "sequential-greedy", "pg-refine", "brute-force"])
def test_fuzz_plan_with_other_planners(name: str) -> None:
    # The same mutations under each other built-in planner of a single decision.
    @settings(SLOW, max_examples=500)
    @given(fz.document(_with_planner(name), json_doc=True))
    def check(case: tuple[str, list[str]]) -> None:
        plan_case(*case)

    check()
