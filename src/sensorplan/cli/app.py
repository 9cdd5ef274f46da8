"""The ``sensorplan`` command line (typer).

Every command is a thin shell over library functions. Bad input of any kind (a file, an
option) ends with exit status 2, one line ``error: <field>: <message>`` on stderr and nothing
on stdout. Heavy modules (the simulator, rich tables, matplotlib) are imported inside the
commands that need them so that ``sensorplan plan`` starts fast.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from .. import __version__
from ..errors import ConfigError, error_line
from ..planners.registry import BUILTIN
from .guards import (Sigterm, Signals, Stopped, animate_drawable, check_environment,
                     check_finite, plot_drawable, quiet_numerics, usage_error_class,
                     usage_line, writing, guard_paths)
from .guards import Terminated as _Terminated
from .options import (AGENTS_PANEL, OUTPUT_PANEL, PANELS, agent_option, agent_option_names,
                      no_flag_placeholders, with_setting_options)

#: For help texts: the built-in names (no installed plugin is looked up for --help);
#: validation always asks the registry.
_PLANNER_NAMES = ", ".join(sorted(BUILTIN)) + ", or package.module:Class"

app = typer.Typer(
    name="sensorplan",
    help="Non-myopic planning of mobile sensor networks for multi-target tracking "
         "(potential games, Lee, Park & Choi).",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode="markdown",
    context_settings={"help_option_names": ["-h", "--help"]},
)

def _print_version(value: bool) -> None:
    if value:
        sys.stdout.write(f"sensorplan {__version__}\n")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[bool, typer.Option(
        "--version", is_eager=True, callback=_print_version,
        help="Print the version and exit.")] = False,
) -> None:
    """Non-myopic planning of mobile sensor networks for multi-target tracking (potential
    games, Lee, Park & Choi)."""


#: Exit status for bad input.
EXIT_BAD_INPUT = 2
#: Exit status when standard output is closed before everything is written to it
#: (``sensorplan simulate ... | head -1``): 128 + SIGPIPE, the status a shell reports for a
#: Unix tool that a closed pipe ended. Nothing is said: the reader chose to stop reading.
EXIT_STDOUT_CLOSED = 141
#: Set this environment variable to see the traceback of an unexpected error.
DEBUG_ENV = "SENSORPLAN_DEBUG"


def _fail(field: str, message: str, code: int = EXIT_BAD_INPUT) -> typer.Exit:
    """Write the one-line error and return the exit to raise (the outcome is decided:
    :func:`_outcome_decided`)."""
    _outcome_decided()
    line = error_line(field, message)
    sys.stdout.flush()
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
    return typer.Exit(code)


@contextmanager
def _bad_input() -> Iterator[None]:
    """Turn a :class:`ConfigError` raised inside a command into the one-line exit 2."""
    try:
        yield
    except ConfigError as exc:
        exc = _hinted(exc)
        raise _fail(exc.field, exc.message) from None


def _hinted(exc: ConfigError) -> ConfigError:
    from ..config.planners import planner_hint

    return planner_hint(exc)


# ------------------------------------------------------------------------------- plan


@app.command()
def plan(
    problem: Annotated[Path | None, typer.Argument(
        metavar="PROBLEM.json", show_default=False,
        help="Single-decision file (JSON: horizon, targets, sensors, planner); "
             "--example prints one.")] = None,
    planner: Annotated[str | None, typer.Option(
        "--planner", metavar="NAME", show_default=False,
        help=f"Planner instead of the file's planner.name ({_PLANNER_NAMES}).")] = None,
    example: Annotated[bool, typer.Option(
        "--example", help="Print a complete decision file (one target, one sensor, the pg "
                          "planner) to start from, and exit.")] = False,
) -> None:
    """Plan one decision and print the plan as JSON on stdout.

    The output has the keys planner, plan (plan[i][k-1] is sensor i's action in epoch k:
    epoch, position, heading, target, measurements), potential (Phi, nats), information
    (Phi's term per target), existence (when the file gives a target's probability of
    existence, which weights its term), converged and sweeps (pg and pg-refine only) and
    seconds (the planner's own time). Bad input exits with status 2 and one line on stderr.

    Example: sensorplan plan --example > problem.json; sensorplan plan problem.json
    """
    if example:
        from ..config.decision import EXAMPLE_PROBLEM

        with _bad_input():
            if problem is not None or planner is not None:
                raise ConfigError("--example", "takes no PROBLEM.json and no --planner")
        sys.stdout.write(EXAMPLE_PROBLEM)
        return
    from .._compiled.aot import ensure_built
    from ..config import load_decision
    from ..config.files import dumps_result
    from ..planners.checks import checked_plan

    with _bad_input():
        if problem is None:
            raise ConfigError("PROBLEM.json", "is required (--example prints one to start from)")
        decision = load_decision(problem, planner)
        ensure_built()          # a first plan compiles the planning kernels ahead of time
        result = checked_plan(decision.make_planner(), decision.problem)
        check_finite(result)
        text = dumps_result(result, decision.problem.existence
                            if decision.existence_given else None)
    sys.stdout.write(text + "\n")


# --------------------------------------------------------------------------- simulate


def simulate(
    config: Annotated[Path | None, typer.Argument(
        metavar="CONFIG.toml", show_default=False,
        help="Scenario file (configs/paper.toml shows every key). Without it, --preset is "
             "used.")] = None,
    preset: Annotated[str | None, typer.Option(
        "--preset", metavar="NAME", show_default=False, rich_help_panel=PANELS["run"],
        help="Built-in scenario instead of a file: paper, radar, urban, slow, swarm "
             "(docs/model.md), search, williams15, vo12 or traffic "
             "(docs/tracking_pmb.md). "
             "[default: paper without a file]")] = None,
    seed: Annotated[int | None, typer.Option(
        "--seed", metavar="S", show_default=False, rich_help_panel=PANELS["run"],
        help="Seed of the run. [default: the file's run.seed, else 0]")] = None,
    out: Annotated[Path, typer.Option(
        "--out", "-o", metavar="DIR", rich_help_panel=OUTPUT_PANEL,
        help="Directory for episode.npz (every array of the run) and episode.png.")
    ] = Path("out/simulate"),
    animate: Annotated[bool, typer.Option(
        "--animate", rich_help_panel=OUTPUT_PANEL,
        help="Also write an animation, one frame per step (DIR/episode.gif).")] = False,
    animation_format: Annotated[str, typer.Option(
        "--animation-format", metavar="gif|mp4", rich_help_panel=OUTPUT_PANEL,
        help="Format of --animate: gif, or mp4 (needs ffmpeg).")] = "gif",
    **settings: Any,
) -> None:
    """Simulate one closed-loop run and summarize it.

    Runs the planner in closed loop on a scenario file or preset, prints the tracking
    errors (RMSE), the sensors' looks and the planning times, and writes the run's arrays
    (DIR/episode.npz) and a figure (DIR/episode.png). Options override the file's
    [planning], [tracker] and [run] tables. Bad input exits with status 2 and one line on
    stderr. Every option in detail: docs/cli.md.

    Example: sensorplan simulate --preset paper --planner pg --horizon 3 --steps-per-epoch 2
    """
    from ..config import load_simulation
    from ..config.files import ensure_out_dir

    with _bad_input():
        cfg = load_simulation(config, preset, {**settings, "seed": seed})
        if animate and cfg.scenario.scan is not None:
            raise ConfigError("--animate", f"the {cfg.scenario.scan} scan has no platforms "
                              "to animate (the run's figures draw them)")
        if animate:
            from ..figures.animation import check_format

            check_format(animation_format)
        ensure_out_dir(out)

    from ..simulation.run import run_episode
    from .console import print_summary, run_with_progress

    try:
        episode = run_with_progress(run_episode, cfg)
    except ConfigError as exc:
        # A planner refusing mid-run (brute force above max_plans) names its own setting;
        # in a scenario file that lives under [planning.planner_params].
        field = exc.field
        if field.startswith("planner."):
            field = "planning.planner_params." + field.removeprefix("planner.")
        raise _fail(field, exc.message) from None
    npz = out / "episode.npz"
    png = out / "episode.png"
    with _bad_input(), writing(out):
        timing = episode.save(npz)
        written = [npz, timing]
        if cfg.scenario.scan is None:
            plot_drawable(episode, cfg.scenario, png)
            written.insert(1, png)
        else:
            sys.stderr.write(f"note: no episode.png for the {cfg.scenario.scan} scan (the run "
                             "figure draws platforms; it has none)\n")
        if animate:
            written.append(animate_drawable(episode, cfg.scenario,
                                            out / f"episode.{animation_format}"))
    print_summary(episode, cfg, written)


app.command()(with_setting_options(simulate))


# ----------------------------------------------------------------------------- agents


def agents(
    config: Annotated[Path | None, typer.Argument(
        metavar="CONFIG.toml", show_default=False,
        help="Scenario file, as for simulate. Without it, --preset is used.")] = None,
    preset: Annotated[str | None, typer.Option(
        "--preset", metavar="NAME", show_default=False, rich_help_panel=PANELS["run"],
        help="Built-in scenario instead of a file: paper. [default: paper without a file]")
    ] = None,
    planner: Annotated[str | None, typer.Option(
        "--planner", metavar="NAME", show_default=False, rich_help_panel=AGENTS_PANEL,
        help="The decentralized planner: dec-jsfp, dec-independent or dec-sequential. "
             "[default: the file's if it is one, else dec-jsfp]")] = None,
    seed: Annotated[int | None, typer.Option(
        "--seed", metavar="S", show_default=False, rich_help_panel=PANELS["run"],
        help="Seed of the run. [default: the file's run.seed, else 0]")] = None,
    out: Annotated[Path, typer.Option(
        "--out", "-o", metavar="DIR", rich_help_panel=OUTPUT_PANEL,
        help="Directory for episode.npz, episode.png and agents.json.")] = Path("out/agents"),
    transport: Annotated[str | None, agent_option("transport")] = None,
    rounds: Annotated[int | None, agent_option("rounds")] = None,
    p_loss: Annotated[float | None, agent_option("p_loss")] = None,
    delay: Annotated[int | None, agent_option("delay")] = None,
    comm_range: Annotated[float | None, agent_option("comm_range")] = None,
    agent_mode: Annotated[str | None, agent_option("mode")] = None,
    **settings: Any,
) -> None:
    """Run one closed-loop episode with one planning agent per platform.

    The platforms negotiate their plans over simulated links (message loss, delay, range)
    with a decentralized planner (docs/decentral.md). Writes what simulate writes plus
    DIR/agents.json (every decision's link log), and prints simulate's summary and a line
    on the links. Every agent process ends with the run, also on Ctrl-C or SIGTERM. Every
    option in detail: docs/cli.md.

    Example: sensorplan agents --preset paper --steps 20 --transport bus --p-loss 0.1
    """
    from ..config.agents import load_agents
    from ..config.files import ensure_out_dir

    links = {"transport": transport, "rounds": rounds, "p_loss": p_loss, "delay": delay,
             "comm_range": comm_range, "mode": agent_mode}
    with _bad_input():
        cfg = load_agents(config, preset, {**settings, "planner": planner, "seed": seed},
                          links, agent_option_names())
        ensure_out_dir(out)

    from ..decentral import run_agents
    from .console import print_links, print_summary, run_with_progress, write_agent_logs

    try:
        with Sigterm():
            episode, logs = run_with_progress(run_agents, cfg)
    except KeyboardInterrupt as exc:
        # run_agents has stopped every agent process on the way out.
        term = isinstance(exc, _Terminated)
        sys.stdout.flush()
        sys.stderr.write("error: terminated\n" if term else "error: interrupted\n")
        raise Stopped(143 if term else 130) from None
    npz, png, log_file = out / "episode.npz", out / "episode.png", out / "agents.json"
    with _bad_input(), writing(out):
        timing = episode.save(npz)
        write_agent_logs(log_file, episode, logs)
        plot_drawable(episode, cfg.scenario, png)
    print_summary(episode, cfg, [npz, png, timing, log_file])
    print_links(logs)


app.command()(with_setting_options(agents, skip=("planner",)))


# ------------------------------------------------------------------------------ study


def _run_study_command(study_obj: Any, out: Path, workers: int | None,
                       scheduler: str | None, label: str,
                       methods: list[str] | None = None) -> Any:
    from ..study import StudyInterrupted, default_workers, run_study
    from ..study.execution import StudyLost
    from .console import study_progress

    parallel = (workers or default_workers()) if scheduler in (None, "local") else 1
    term = Sigterm()
    try:
        with _bad_input(), term, study_progress(label, parallel) as progress:
            return run_study(study_obj, out, workers=workers, scheduler=scheduler,
                             progress=progress, methods=methods)
    except StudyInterrupted as exc:
        # run_study has stopped the workers; a rerun resumes.
        sys.stdout.flush()
        sys.stderr.write(f"interrupted: {exc.done} of {exc.total} (run, method) pairs are "
                         f"saved in {out}; run the same command again to resume\n")
        raise Stopped(143 if term.fired else 130) from None
    except StudyLost as exc:
        raise _fail("--scheduler", f"the Dask cluster lost the study: every worker holding "
                    f"it is gone ({exc.why}); {exc.done} of {exc.total} (run, method) pairs "
                    f"are saved in {out}; run the same command again to resume",
                    code=1) from None


_WORKERS_HELP = ("Worker processes (1: this process; with --scheduler local, the "
                 "cluster's). [default: the cores]")
_DEMO_WORKERS_HELP = ("Worker processes of the local pool (1 runs in this process). "
                      "[default: the number of cores]")
_SCHEDULER_HELP = ("Run on Dask: a scheduler's address (tcp://host:8786) or local (a "
                   "cluster started here).")

#: The pool and scheduler options of the commands that run studies.
_WorkersOption = Annotated[int | None, typer.Option(
    "--workers", "-j", metavar="N", show_default=False, help=_WORKERS_HELP)]
_SchedulerOption = Annotated[str | None, typer.Option(
    "--scheduler", metavar="ADDRESS", show_default=False, help=_SCHEDULER_HELP)]

@app.command()
def study(
    study_file: Annotated[Path, typer.Argument(
        metavar="STUDY.toml", show_default=False,
        help="Study file: scenario, runs, steps, seed, [[methods]] (studies/paper.toml).")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="DIR", show_default=False,
        help="Study directory (created; an existing one of the same study is resumed). "
             "[default: runs/NAME for NAME.toml]")] = None,
    workers: _WorkersOption = None,
    scheduler: _SchedulerOption = None,
    methods: Annotated[str | None, typer.Option(
        "--methods", "-m", metavar="NAME,...", show_default=False,
        help="Run only these methods (comma-separated); the others later into the same "
             "DIR (until then report reads those that ran).")] = None,
) -> None:
    """Run a Monte Carlo study: every method on the same paired runs.

    Writes DIR/config.resolved.json (the study with every default filled in), one small
    file per finished (run, method) under DIR/parts/, then the tidy tables
    DIR/steps.parquet, DIR/decisions.parquet and DIR/sensors.parquet, and DIR/meta.json
    (versions, seed, wall time). Interrupted (Ctrl-C, a killed process)? Run the same
    command again: only the missing pairs run. A finished study is not recomputed; a DIR
    holding a different study is an error. Results do not depend on --workers or
    --scheduler (except the planners' wall times).

    Example: sensorplan study studies/paper.toml --out runs/paper --workers 2
    """
    from ..study import load_study

    with _bad_input():
        study_obj = load_study(study_file)
        if workers is not None and workers < 1:
            raise ConfigError("--workers", f"must be an integer >= 1, got {workers}")
        chosen = None if methods is None else [m.strip() for m in methods.split(",")]
        if chosen is not None and not all(chosen):
            raise ConfigError("--methods", f"must be comma-separated method names, got "
                              f"{methods!r}")
    out = out if out is not None else Path("runs") / study_file.stem
    res = _run_study_command(study_obj, out, workers, scheduler, f"study {study_file.stem}",
                             chosen)
    left = res.total - res.done
    if res.ran == 0 and not left:
        print(f"{out}: study already complete ({res.total} (run, method) pairs); nothing to "
              "run")
    elif res.ran == 0:
        print(f"{out}: {', '.join(chosen or [])} already done; {left} of {res.total} "
              "(run, method) pairs of the study's other methods still to run")
    elif left:
        print(f"{out}: ran {res.ran} (run, method) pairs in {res.wall:.1f} s; {left} of "
              f"{res.total} pairs of the study's other methods still to run (the tables are "
              "written when the last has run)")
    else:
        print(f"{out}: ran {res.ran} of {res.total} (run, method) pairs in "
              f"{res.wall:.1f} s; tables: steps.parquet, decisions.parquet, sensors.parquet")
    print(f"next: sensorplan report {out}")


@app.command()
def grid(
    grid_file: Annotated[Path, typer.Argument(
        metavar="GRID.toml", show_default=False,
        help="Grid file: a study file plus design, [[axes]] and [[comparisons]] "
             "(studies/lookahead_map.toml).")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="DIR", show_default=False,
        help="Grid directory (created; an existing one of the same grid is resumed). "
             "[default: runs/NAME for NAME.toml]")] = None,
    workers: _WorkersOption = None,
    scheduler: _SchedulerOption = None,
) -> None:
    """Run a grid study: the same methods over scenario variants (cells), to map where one
    method beats another.

    Each cell varies the file's scenario or settings along the axes (sensor_speed,
    min_ground_range, town, snr_ref_db, clutter_rate, setting): a star design varies one
    axis at a time around the base values, a full design takes every combination. Writes
    DIR/grid.json (the grid with every cell) and runs each cell as a study into DIR/CELL
    (e.g. DIR/base, DIR/sensor_speed=0.25), one cell after another, all with the same seed
    and runs. Resumes like a study: run the same command again; a changed grid in DIR is
    an error. Then sensorplan report DIR draws heat maps of the paired differences.

    Example: sensorplan grid studies/lookahead_map.toml --out runs/lookahead_map -j 2
    """
    from .commands import grid_command

    with _bad_input():
        code = grid_command(grid_file, out, workers, scheduler)
    if code:
        raise Stopped(code)           # it said what is saved: not typer's bare 130 status


# ----------------------------------------------------------------------------- report


@app.command()
def report(
    study_dir: Annotated[Path, typer.Argument(
        metavar="DIR", show_default=False,
        help="A study directory (sensorplan study --out) or a grid directory (sensorplan "
             "grid --out).")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="REPORT_DIR", show_default=False,
        help="Where to write the report. [default: DIR/report]")] = None,
) -> None:
    """Write figures, a self-contained HTML page and a markdown summary of a study.

    Reads only the study directory's files. DIR/report/ gets report.html (figures
    embedded, opens from disk with no network), summary.md (the tables, with links to the
    figures) and the PNG figures. An unfinished study is reported on the runs that every
    method has finished, and says so. For a grid directory: one heat map, table and
    verdict per comparison, cells that have not run in grey.

    Example: sensorplan report runs/paper
    """
    from ..config.files import ensure_out_dir
    from ..report import write_report

    with _bad_input():
        if not study_dir.is_dir():
            raise ConfigError("DIR", f"{study_dir}: no such directory" if not
                              study_dir.exists() else f"{study_dir} is not a directory")
        if (study_dir / "config.resolved.json").exists():
            # Checked before the figures are drawn: a file or a read-only place fails now.
            ensure_out_dir(out if out is not None else study_dir / "report")
        with writing(out if out is not None else study_dir / "report"):
            written = write_report(study_dir, out)
    if not written.complete:
        sys.stderr.write(f"warning: {study_dir} is not finished; the report covers "
                         f"{written.runs} run(s)\n")
    print(f"report: {written.html}")
    print(f"summary: {written.markdown}")
    print(f"figures: {len(written.figures)} PNG files in {written.html.parent}")


# ----------------------------------------------------------------------------- replay


@app.command()
def replay(
    study_dir: Annotated[Path, typer.Argument(
        metavar="DIR", show_default=False, help="A study directory (sensorplan study --out).")],
    run: Annotated[int, typer.Option(
        "--run", "-r", metavar="R", show_default=False,
        help="Run index, 0 .. runs-1.")],
    method: Annotated[str, typer.Option(
        "--method", "-m", metavar="NAME", show_default=False,
        help="Method name, as in the study file and the report.")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="OUT", show_default=False,
        help="Where to write the files. [default: DIR/replay/run-R-NAME]")] = None,
    animate: Annotated[bool, typer.Option(
        "--animate/--no-animate", help="Write the animation.")] = True,
    animation_format: Annotated[str, typer.Option(
        "--animation-format", metavar="gif|mp4",
        help="gif (always available) or mp4 (needs ffmpeg).")] = "gif",
) -> None:
    """Re-simulate one run of one method of a study and draw it.

    Runs method NAME on run R with the study's configuration (DIR/config.resolved.json)
    and the run's seed, checks that it reproduces what the study stored for that run, and
    writes what simulate writes (episode.npz, episode.png) plus an animation
    (episode.gif). The report names the best and worst runs to look at. A run whose
    tracker keeps an undetected intensity (pmb) is drawn over it as a heat map (expected
    undetected targets per km^2, with a colour bar); search looks are drawn as the beam's
    sector with its bearing, and tracks found by them are ringed.

    Example: sensorplan replay runs/paper --run 9 --method ours/olf-pg
    """
    from .commands import replay_command

    with _bad_input():
        replay_command(study_dir, run, method, out, animate, animation_format)


# ------------------------------------------------------------------------------- demo


@app.command()
def demo(
    scenario: Annotated[str, typer.Option(
        "--scenario", metavar="slow|paper",
        help="slow: slow platforms, where looking ahead pays; paper: the paper's "
             "scenario.")] = "slow",
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="DIR", show_default=False,
        help="Study directory of the demo. [default: out/demo; out/demo-paper with "
             "--scenario paper]")] = None,
    workers: Annotated[int | None, typer.Option(
        "--workers", "-j", metavar="N", show_default=False, help=_DEMO_WORKERS_HELP)] = None,
) -> None:
    """Run a small study and write its report; print where the report is.

    By default the paper's scenario with slow platforms (5 or 10 m per step): random,
    myopic planning and planning three epochs ahead on the same paired runs, where looking
    ahead pays (studies/demo.toml, built in; about a minute on 2 cores). --scenario paper
    runs the paper's scenario instead (studies/demo_paper.toml). A second call reuses the
    finished study and only rewrites the report.

    Example: sensorplan demo --out out/demo
    """
    from .. import study as studies
    from ..report import write_report

    with _bad_input():
        if workers is not None and workers < 1:
            raise ConfigError("--workers", f"must be an integer >= 1, got {workers}")
        study_obj = studies.demo_study(scenario)
    if out is None:
        out = Path("out/demo") if scenario == "slow" else Path(f"out/demo-{scenario}")
    res = _run_study_command(study_obj, out, workers, None, "demo study")
    with _bad_input(), writing(out / "report"):
        written = write_report(out, None)
    what = "already complete" if res.ran == 0 else f"{res.ran} (run, method) pairs in " \
                                                   f"{res.wall:.1f} s"
    print(f"demo study ({scenario}): {len(study_obj.methods)} methods x {study_obj.runs} runs "
          f"x {study_obj.steps} steps ({what})")
    print(f"report: {written.html}")
    print(f"open it in a browser, e.g. file://{written.html.resolve()}")


# ---------------------------------------------------------------------------- compile


@app.command(name="compile")
def compile_kernels() -> None:
    """Compile the numerical kernels once, ahead of need (make runs it after installing).

    Fills numba's disk cache with the planning kernels and builds the ahead-of-time module
    that lets sensorplan plan start without numba (about a minute on 2 cores; without it
    the first plan does it). Notes on stderr, what is in place on stdout. An interrupted
    call leaves complete files or none; a second call with everything current does
    nothing and says so.

    Example: sensorplan compile
    """
    from .._compiled.prepare import compile_kernels as compile_all
    from .._compiled.prepare import status_line

    result = compile_all()
    print(status_line(result))


# ------------------------------------------------------------------------------- main


def cli_command() -> Any:
    """The click command of :data:`app` as ``main`` runs it: path arguments checked as they
    are parsed, and no value placeholder shown for a flag."""
    return no_flag_placeholders(guard_paths(typer.main.get_command(app)))


def main(argv: Sequence[str] | None = None) -> None:
    """Console entry point: run the app, map every failure to an exit status and one line.

    Exit status: 0 success, 2 bad input (file, options or environment), 1 an unexpected
    error (set ``SENSORPLAN_DEBUG=1`` for its traceback) or a Dask cluster that lost a
    study, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM), 141 standard output closed
    before the output was written (a pipe into ``head``), without a word.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    global _PROCESS
    _PROCESS = argv is None                 # the command line's own process, not a caller
    if not args:
        args = ["--help"]
    signals = Signals()
    try:
        with quiet_numerics(DEBUG_ENV), signals:
            command = cli_command()                             # Ctrl-C here: one line
            if not {"--help", "-h", "--version"} & set(args):
                check_environment()
            code = command.main(args=args, prog_name="sensorplan", standalone_mode=False)
            sys.stdout.flush()          # a closed pipe shows here, not at the interpreter's exit
        if code == 130 and signals.received is not None:
            _outcome_decided()
            # typer turns a KeyboardInterrupt (and so a SIGTERM) into a bare status 130.
            term = signals.received == "TERM"
            sys.stdout.flush()
            sys.stderr.write("error: terminated\n" if term else "error: interrupted\n")
            code = 143 if term else 130
    except Stopped as exc:
        code = exc.code
    except BrokenPipeError:
        code = _stdout_closed()
    except SystemExit as exc:
        # click and rich end a command whose stdout closed with a bare exit status 1.
        if not isinstance(exc.__context__, BrokenPipeError):
            raise
        code = _stdout_closed()
    except usage_error_class() as exc:
        _outcome_decided()
        try:
            field, message = usage_line(exc, args)
        except Exception:  # noqa: BLE001 - never a traceback for a usage error
            field, message = "usage", str(exc)
        _fail(field, message)
        code = EXIT_BAD_INPUT
    except ConfigError as exc:
        _outcome_decided()
        exc = _hinted(exc)
        _fail(exc.field, exc.message)
        code = EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        _outcome_decided()
        term = isinstance(exc, _Terminated)
        sys.stderr.write("error: terminated\n" if term else "error: interrupted\n")
        code = 143 if term else 130
    except typer.Abort:
        _outcome_decided()
        sys.stderr.write("error: aborted\n")
        code = 1
    except Exception as exc:  # noqa: BLE001 - one line instead of a traceback
        _outcome_decided()
        if os.environ.get(DEBUG_ENV):
            raise
        _fail("internal error", f"{type(exc).__name__}: {exc} (set {DEBUG_ENV}=1 for the "
              "traceback)", code=1)
        code = 1
    sys.exit(code if isinstance(code, int) else 0)


#: Whether :func:`main` runs as the command line's own process (not called by a program).
_PROCESS = False


def _outcome_decided() -> None:
    """The command's outcome is decided and about to be said in one line: a Ctrl-C or
    SIGTERM from now on is ignored, so that it cannot add a second line ("error:
    interrupted" after the error) or change the exit status. Only in the command line's
    own process (which ends next): a program calling :func:`main` keeps its handlers."""
    import signal

    if not _PROCESS:
        return
    with contextlib.suppress(ValueError):          # not the main thread: not ours
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _stdout_closed() -> int:
    """Point standard output at the null device, so that nothing fails or complains when the
    interpreter flushes it at exit; return :data:`EXIT_STDOUT_CLOSED`."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass                        # not a file descriptor (a test's capture): nothing to do
    return EXIT_STDOUT_CLOSED


if __name__ == "__main__":  # pragma: no cover
    main()
