"""The ``sensorplan`` command line (typer).

Every command is a thin shell over library functions. Bad input of any kind (a file, an
option) ends with exit status 2, one line ``error: <field>: <message>`` on stderr and nothing
on stdout. Heavy modules (the simulator, rich tables, matplotlib) are imported inside the
commands that need them so that ``sensorplan plan`` starts fast.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from . import __version__
from .errors import ConfigError
from .planners.registry import BUILTIN
from .settings import all_settings, default_of, field_type

#: For help texts: the built-in names (no installed plugin is looked up for --help);
#: validation always asks the registry.
_PLANNER_NAMES = ", ".join(sorted(BUILTIN)) + ", an installed plugin's name or " \
    "package.module:Class"

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


#: Exit status for bad input (SPEC 7).
EXIT_BAD_INPUT = 2
#: Set this environment variable to see the traceback of an unexpected error.
DEBUG_ENV = "SENSORPLAN_DEBUG"


def _fail(field: str, message: str, code: int = EXIT_BAD_INPUT) -> typer.Exit:
    """Write the one-line error and return the exit to raise."""
    line = f"error: {field}: {message}".replace("\r", " ").replace("\n", " ")
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
        raise _fail(exc.field, exc.message) from None


# ------------------------------------------------------------------------------- plan


@app.command()
def plan(
    problem: Annotated[Path, typer.Argument(
        metavar="PROBLEM.json", show_default=False,
        help="Single-decision file (SPEC 7): horizon, targets (mean, cov), sensors "
             "(position, heading, radar parameters), optional planner settings.")],
    planner: Annotated[str | None, typer.Option(
        "--planner", metavar="NAME", show_default=False,
        help=f"Planner to use instead of the file's planner.name ({_PLANNER_NAMES}). "
             "File settings it does not take are ignored.")] = None,
) -> None:
    """Plan one decision and print the plan as JSON on stdout.

    The output has the keys planner, plan (plan[i][k-1] is sensor i's action in epoch k:
    epoch, position, heading, target, measurements), potential (Phi, nats), information
    (Phi's term per target), converged and sweeps (pg and pg-refine only) and seconds (the
    planner's own time). Bad input exits with status 2 and one line on stderr.

    Example: sensorplan plan problem.json --planner pg
    """
    from .config import load_decision
    from .io import dumps_result

    with _bad_input():
        decision = load_decision(problem, planner)
        chosen = decision.make_planner()
        result = chosen.plan(decision.problem)
    sys.stdout.write(dumps_result(result) + "\n")


# --------------------------------------------------------------------------- simulate


def simulate(
    config: Annotated[Path | None, typer.Argument(
        metavar="CONFIG.toml", show_default=False,
        help="Scenario file (see configs/paper.toml for every key). Without it, --preset "
             "is used.")] = None,
    preset: Annotated[str | None, typer.Option(
        "--preset", metavar="NAME", show_default=False,
        help="Built-in scenario instead of a file: 'paper' (SPEC 1: 5 targets, 3 sensors, "
             "random start each run). The default when no file is given.")] = None,
    seed: Annotated[int | None, typer.Option(
        "--seed", metavar="S", show_default=False,
        help="Seed of the run (truth, initial estimates, noise and planner streams). "
             "[default: file's run.seed, else 0]")] = None,
    out: Annotated[Path, typer.Option(
        "--out", "-o", metavar="DIR",
        help="Directory for episode.npz (every array of the run) and episode.png.")
    ] = Path("out/simulate"),
    **settings: Any,
) -> None:
    """Simulate one closed-loop run and summarize it.

    Runs the planner in closed loop (SPEC 5) on a scenario file or preset, prints tables
    (RMSE per target and per target kind, measurements and missed looks per sensor,
    planning time per decision) and writes the run's arrays (DIR/episode.npz, readable with
    sensorplan.simulation.Episode.load) and a figure (DIR/episode.png).

    Options override the scenario file's [planning], [tracker] and [run] tables; a
    [default] applies when neither sets a value. Bad input exits with status 2 and one line
    on stderr.

    Example: sensorplan simulate --preset paper --planner pg --horizon 3 --steps-per-epoch 2
    """
    from .config import load_simulation
    from .io import ensure_out_dir

    with _bad_input():
        cfg = load_simulation(config, preset, {**settings, "seed": seed})
        ensure_out_dir(out)

    from .simulation import run_episode

    try:
        episode = _run_with_progress(run_episode, cfg)
    except ConfigError as exc:
        # A planner refusing mid-run (brute force above max_plans) names its own setting;
        # in a scenario file that lives under [planning.planner_params].
        field = exc.field
        if field.startswith("planner."):
            field = "planning.planner_params." + field.removeprefix("planner.")
        raise _fail(field, exc.message) from None
    npz = out / "episode.npz"
    png = out / "episode.png"
    timing = episode.save(npz)
    from .plotting import plot_episode

    plot_episode(episode, cfg.scenario, png)
    _print_summary(episode, cfg, [npz, png, timing])


def _setting_options() -> list[inspect.Parameter]:
    """An option of ``simulate`` for every run setting that declares option names, with its
    help, value placeholder and default from the declaration (sensorplan.settings)."""
    params = []
    for cls, _, f, s in all_settings():
        if not s.cli:
            continue
        # Choices known only at run time cannot be written into the help sentence.
        if callable(s.choices):
            text = s.help.removesuffix(".") + f" ({', '.join(s.allowed())})."
        elif s.names is not None:
            text = s.help.removesuffix(".") + f" ({', '.join(s.names())}, ...)."
        else:
            text = s.help
        option = typer.Option(*s.cli, metavar=s.metavar, show_default=False,
                              help=f"{text} [default: {default_of(f)}]")
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=None,
                                        annotation=Annotated[field_type(cls, f.name) | None,
                                                             option]))
    return params


# typer reads the command's options from its signature (it calls it with keywords only).
_fixed = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
          for p in inspect.signature(simulate, eval_str=True).parameters.values()
          if p.kind is not inspect.Parameter.VAR_KEYWORD]
simulate.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
    _fixed[:2] + _setting_options() + _fixed[2:])
app.command()(simulate)


def _run_with_progress(run_episode: Any, cfg: Any) -> Any:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, \
        TimeElapsedColumn, TimeRemainingColumn

    console = Console(stderr=True)
    columns = (TextColumn("simulating"), BarColumn(), MofNCompleteColumn(),
               TextColumn("steps"), TimeElapsedColumn(), TimeRemainingColumn())
    # A bar in a log file is noise: show it only on a terminal.
    with Progress(*columns, console=console, transient=True,
                  disable=not console.is_terminal) as progress:
        task = progress.add_task("simulate", total=cfg.settings.steps)

        def report(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        return run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=report)


def _print_summary(episode: Any, cfg: Any, written: Sequence[Path]) -> None:
    import numpy as np
    from rich.console import Console
    from rich.table import Table

    from .study.metrics import LOST_THRESHOLD, NEES_HIGH, episode_consistency, episode_errors

    console = Console()
    s = cfg.settings
    console.print(f"[bold]{s.planner}[/], K = {s.horizon}, e = {s.steps_per_epoch}, "
                  f"{s.execution.upper()}, {s.steps} steps, seed {cfg.seed}", highlight=False)
    tracker = ", ".join(f"{meta.label or f.name} {getattr(s.tracker, f.name)}"
                        for _, path, f, meta in all_settings() if path.startswith("tracker."))
    console.print(f"visibility {s.visibility}, objective {s.objective}, {tracker}",
                  highlight=False)

    measured = np.asarray(episode.measured)[1:]                # (S, M, N)
    tracks = Table(title="Position error over steps 1..S (m)",
                   caption=f"lost: share of steps with error > {LOST_THRESHOLD:g} m; measured: "
                           "steps with at least one measurement; ANEES: average NEES (4 for "
                           "an honest filter); restarts: tracks restarted from a detection")
    for name in ("target", "kind", "RMSE", "mean", "final", "lost", "measured", "ANEES",
                 "restarts"):
        tracks.add_column(name, justify="left" if name in ("target", "kind") else "right")
    rows = episode_errors(episode)
    for i, row in enumerate(rows):
        if i and row.target == "all" and rows[i - 1].target != "all":
            tracks.add_section()                   # per-target rows, then the groups
        tracks.add_row(row.target, row.kind, f"{row.rmse:.1f}", f"{row.mean:.1f}",
                       f"{row.final:.1f}", f"{row.lost_share:.0%}", str(row.measured),
                       f"{row.anees:.2f}", str(row.restarts),
                       style="bold" if row.target == "all" else None)
    console.print(tracks)
    c = episode_consistency(episode)
    console.print(f"track consistency: ANEES {c['anees']:.2f} (95 % band of an honest filter "
                  f"[{c['band_lo']:.2f}, {c['band_hi']:.2f}]), NEES > {NEES_HIGH:.2f} on "
                  f"{100 * c['high_share']:.1f} % of target-steps (1 % when honest), "
                  f"{c['restarts']} restarts, {c['map_corrections']} map corrections",
                  highlight=False)

    looked = np.asarray(episode.looked)[1:]                    # (S, N)
    missed = np.asarray(episode.missed)[1:]                    # (S, N)
    sensors = Table(title="Sensors (steps 1..S)")
    for name in ("sensor", "altitude (m)", "looks", "measurements", "missed looks"):
        sensors.add_column(name, justify="left" if name == "sensor" else "right")
    for i, spec in enumerate(cfg.scenario.sensors):
        sensors.add_row(str(i), f"{float(spec.params.altitude):g}",
                        str(int((looked[:, i] >= 0).sum())),
                        str(int(measured[:, :, i].sum())), str(int(missed[:, i].sum())))
    console.print(sensors)

    secs = 1e3 * np.asarray(episode.planning_seconds)
    conv = np.asarray(episode.converged, dtype=float)
    sweeps = np.asarray(episode.sweeps, dtype=float)
    plans = Table(title="Planning per decision",
                  caption="time: wall time of the planner call (ms)")
    for name in ("decisions", "mean ms", "median ms", "max ms", "mean Phi", "converged",
                 "sweeps"):
        plans.add_column(name, justify="right")

    def stat(values: Any, fmt: str, fn: Any = np.mean) -> str:
        ok = values[~np.isnan(values)] if values.size else values
        return format(float(fn(ok)), fmt) if ok.size else "-"

    plans.add_row(str(secs.size), stat(secs, ".2f"), stat(secs, ".2f", np.median),
                  stat(secs, ".2f", np.max), stat(np.asarray(episode.potential), ".3f"),
                  stat(conv, ".0%"), stat(sweeps, ".1f"))
    console.print(plans)
    console.print("wrote " + ", ".join(str(p) for p in written), highlight=False)


# ------------------------------------------------------------------------------ study


def _study_progress(label: str) -> Any:
    """Context manager yielding a ``progress(done, total, already)`` callback for
    :func:`sensorplan.study.run_study`: a rich bar with ETA on a terminal, a plain
    line about every 10 % or every minute (and at the end) otherwise."""
    import time

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, \
        TimeElapsedColumn, TimeRemainingColumn

    console = Console(stderr=True)

    @contextmanager
    def bar() -> Iterator[Any]:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("(run, method) pairs"), TimeElapsedColumn(),
                   TextColumn("ETA"), TimeRemainingColumn())
        progress = Progress(*columns, console=console, transient=False)
        task = progress.add_task(label, total=None)
        started = False

        def report(done: int, total: int, already: int) -> None:
            nonlocal started
            if not started:
                # Started on the first report only, so that an error found before any
                # work (a changed study) prints its one line and nothing else.
                progress.start()
                started = True
            progress.update(task, completed=done, total=total,
                            description=label + (f" ({already} already done)"
                                                 if already else ""))
        try:
            yield report
        finally:
            if started:
                progress.stop()

    @contextmanager
    def lines() -> Iterator[Any]:
        state = {"start": time.perf_counter(), "next": 0.0, "last": time.perf_counter()}

        def report(done: int, total: int, already: int) -> None:
            now = time.perf_counter()
            if done == 0:
                state["start"] = state["last"] = now
                console.print(f"{label}: {total} (run, method) pairs to run"
                              + (f", {already} already done" if already else ""),
                              highlight=False)
                return
            # A line about every 10 % or every minute, and at the end.
            if (done / total + 1e-12 < state["next"] and now - state["last"] < 60
                    and done != total):
                return
            state["next"] = done / total + 0.1
            state["last"] = now
            elapsed = now - state["start"]
            eta = elapsed / done * (total - done)
            console.print(f"{label}: {done}/{total} done, {elapsed:.0f} s elapsed, "
                          f"ETA {eta:.0f} s", highlight=False)
        yield report

    return bar() if console.is_terminal else lines()


def _run_study_command(study_obj: Any, out: Path, workers: int | None,
                       scheduler: str | None, label: str) -> Any:
    from .study import StudyInterrupted, run_study

    try:
        with _bad_input(), _study_progress(label) as progress:
            return run_study(study_obj, out, workers=workers, scheduler=scheduler,
                             progress=progress)
    except StudyInterrupted as exc:
        sys.stdout.flush()
        sys.stderr.write(f"interrupted: {exc.done} of {exc.total} (run, method) pairs are "
                         f"saved in {out}; run the same command again to resume\n")
        raise typer.Exit(130) from None


_WORKERS_HELP = ("Worker processes of the local pool (1 runs in this process). With "
                 "--scheduler local: the LocalCluster's workers. [default: the number of "
                 "cores]")
_SCHEDULER_HELP = ("Run on Dask distributed: a scheduler address (tcp://host:8786; its "
                   "workers need sensorplan installed) or 'local' for a LocalCluster "
                   "started here.")


@app.command()
def study(
    study_file: Annotated[Path, typer.Argument(
        metavar="STUDY.toml", show_default=False,
        help="Study file: scenario (preset or file), runs, steps, seed and [[methods]] "
             "(see studies/paper.toml and docs/studies.md).")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="DIR", show_default=False,
        help="Study directory (created; an existing one of the same study is resumed). "
             "[default: runs/NAME for NAME.toml]")] = None,
    workers: Annotated[int | None, typer.Option(
        "--workers", "-j", metavar="N", show_default=False, help=_WORKERS_HELP)] = None,
    scheduler: Annotated[str | None, typer.Option(
        "--scheduler", metavar="ADDRESS", show_default=False, help=_SCHEDULER_HELP)] = None,
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
    from .study import load_study

    with _bad_input():
        study_obj = load_study(study_file)
        if workers is not None and workers < 1:
            raise ConfigError("--workers", f"must be an integer >= 1, got {workers}")
    out = out if out is not None else Path("runs") / study_file.stem
    res = _run_study_command(study_obj, out, workers, scheduler, f"study {study_file.stem}")
    if res.ran == 0:
        print(f"{out}: study already complete ({res.total} (run, method) pairs); nothing to "
              "run")
    else:
        print(f"{out}: ran {res.ran} of {res.total} (run, method) pairs in "
              f"{res.wall:.1f} s; tables: steps.parquet, decisions.parquet, sensors.parquet")
    print(f"next: sensorplan report {out}")


# ----------------------------------------------------------------------------- report


@app.command()
def report(
    study_dir: Annotated[Path, typer.Argument(
        metavar="DIR", show_default=False, help="A study directory (sensorplan study --out).")],
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", metavar="REPORT_DIR", show_default=False,
        help="Where to write the report. [default: DIR/report]")] = None,
) -> None:
    """Write figures, a self-contained HTML page and a markdown summary of a study.

    Reads only the study directory's files. DIR/report/ gets report.html (figures
    embedded, opens from disk with no network), summary.md (the tables, with links to the
    figures) and the PNG figures. An unfinished study is reported on the runs that every
    method has finished, and says so.

    Example: sensorplan report runs/paper
    """
    from .report import write_report

    with _bad_input():
        written = write_report(study_dir, out)
    if not written.complete:
        sys.stderr.write(f"warning: {study_dir} is not finished; the report covers "
                         f"{written.runs} run(s)\n")
    print(f"report: {written.html}")
    print(f"summary: {written.markdown}")
    print(f"figures: {len(written.figures)} PNG files in {written.html.parent}")


# ------------------------------------------------------------------------------- demo


@app.command()
def demo(
    out: Annotated[Path, typer.Option(
        "--out", "-o", metavar="DIR", help="Study directory of the demo.")] = Path("out/demo"),
    workers: Annotated[int | None, typer.Option(
        "--workers", "-j", metavar="N", show_default=False, help=_WORKERS_HELP)] = None,
) -> None:
    """Run a small study (the paper scenario, a few short paired runs, our defaults) and
    write its report; print where the report is.

    The study is studies/demo.toml (built in). Takes well under two minutes on 2 cores;
    a second call reuses the finished study and only rewrites the report.

    Example: sensorplan demo --out out/demo
    """
    from . import study as studies
    from .report import write_report

    with _bad_input():
        if workers is not None and workers < 1:
            raise ConfigError("--workers", f"must be an integer >= 1, got {workers}")
        study_obj = studies.demo_study()
    res = _run_study_command(study_obj, out, workers, None, "demo study")
    with _bad_input():
        written = write_report(out, None)
    what = "already complete" if res.ran == 0 else f"{res.ran} (run, method) pairs in " \
                                                   f"{res.wall:.1f} s"
    print(f"demo study: {len(study_obj.methods)} methods x {study_obj.runs} runs x "
          f"{study_obj.steps} steps ({what})")
    print(f"report: {written.html}")
    print(f"open it in a browser, e.g. file://{written.html.resolve()}")


# ------------------------------------------------------------------------------- main


def _usage_error_class() -> type[BaseException]:
    # typer raises click's UsageError (vendored in recent typer, the click package in
    # older ones); reach it through the public BadParameter instead of a private import.
    return next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


def _usage_line(exc: Any) -> tuple[str, str]:
    """(field, message) of a command-line usage error."""
    param = getattr(exc, "param", None)
    if param is not None:
        opts = [o for o in getattr(param, "opts", []) if o.startswith("--")]
        name = getattr(param, "metavar", None) or (param.name or "argument").upper()
        field = opts[0] if opts else name
        # A missing argument or option carries no message of its own.
        return field, getattr(exc, "message", "") or "is required"
    option = getattr(exc, "option_name", None)
    if option:
        message = exc.format_message()
        prefix = f"No such option: {option}"
        if message.startswith(prefix):
            message = "no such option" + message[len(prefix):]
        return option, message
    return "usage", exc.format_message()


def main(argv: Sequence[str] | None = None) -> None:
    """Console entry point: run the app, map every failure to an exit status and one line.

    Exit status: 0 success, 2 bad input (file or options), 1 an unexpected error (set
    ``SENSORPLAN_DEBUG=1`` for its traceback), 130 interrupted.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        args = ["--help"]
    command = typer.main.get_command(app)
    try:
        code = command.main(args=args, prog_name="sensorplan", standalone_mode=False)
    except _usage_error_class() as exc:
        try:
            field, message = _usage_line(exc)
        except Exception:  # noqa: BLE001 - never a traceback for a usage error
            field, message = "usage", str(exc)
        _fail(field, message)
        code = EXIT_BAD_INPUT
    except ConfigError as exc:
        _fail(exc.field, exc.message)
        code = EXIT_BAD_INPUT
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        code = 130
    except typer.Abort:
        sys.stderr.write("error: aborted\n")
        code = 1
    except Exception as exc:  # noqa: BLE001 - one line instead of a traceback
        if os.environ.get(DEBUG_ENV):
            raise
        _fail("internal error", f"{type(exc).__name__}: {exc} (set {DEBUG_ENV}=1 for the "
              "traceback)", code=1)
        code = 1
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
