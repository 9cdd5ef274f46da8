"""What the command line prints: progress bars and the summary tables of a run (rich).

Imported by the commands that print them, so that ``sensorplan --help`` and
``sensorplan plan`` do not load rich's tables.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .settings import all_settings


def run_with_progress(run_episode: Any, cfg: Any) -> Any:
    """``run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=...)`` with a progress
    bar on stderr when it is a terminal."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, \
        TimeElapsedColumn, TimeRemainingColumn

    import time

    console = Console(stderr=True)
    columns = (TextColumn("simulating"), BarColumn(), MofNCompleteColumn(),
               TextColumn("steps"), TimeElapsedColumn(), TimeRemainingColumn())
    # A bar in a log file is noise: on a terminal a bar, otherwise a plain line about
    # every 10 % of the steps or every minute, whichever comes first (long runs only).
    terminal = console.is_terminal
    start = last = time.monotonic()
    with Progress(*columns, console=console, transient=True,
                  disable=not terminal) as progress:
        task = progress.add_task("simulate", total=cfg.settings.steps)

        def report(done: int, total: int) -> None:
            nonlocal last
            progress.update(task, completed=done, total=total)
            now = time.monotonic()
            if terminal or now - start < 10.0:
                return
            if now - last >= 60.0 or done == total or done % max(1, total // 10) == 0:
                last = now
                eta = (now - start) * (total - done) / max(done, 1)
                console.print(f"simulated {done}/{total} steps, {now - start:.0f} s "
                              f"elapsed, ETA {eta:.0f} s", highlight=False)

        return run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=report)


#: Tables list every target and sensor up to this many; beyond it the first few and a note.
MAX_ROWS = 20


def print_summary(episode: Any, cfg: Any, written: Sequence[Path]) -> None:
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
    per_target = [r for r in rows if r.target != "all"]
    if len(per_target) > MAX_ROWS:
        # A swarm's hundreds of rows drown the totals: the first few, then the groups.
        rows = per_target[:MAX_ROWS // 2] + [r for r in rows if r.target == "all"]
        tracks.caption = (f"targets 0-{MAX_ROWS // 2 - 1} of {len(per_target)} shown "
                          "(episode.npz holds them all); " + str(tracks.caption))
    for i, row in enumerate(rows):
        if i and row.target == "all" and rows[i - 1].target != "all":
            if len(per_target) > MAX_ROWS:
                tracks.add_row("...")
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
    n_sensors = len(cfg.scenario.sensors)
    for i, spec in enumerate(cfg.scenario.sensors):
        if n_sensors > MAX_ROWS and i == MAX_ROWS // 2:
            sensors.add_row("...", "", "", "", "")
            sensors.caption = f"sensors 0-{i - 1} of {n_sensors} shown; all: every sensor"
            break
        sensors.add_row(str(i), f"{float(spec.params.altitude):g}",
                        str(int((looked[:, i] >= 0).sum())),
                        str(int(measured[:, :, i].sum())), str(int(missed[:, i].sum())))
    if n_sensors > 1:
        sensors.add_section()
        sensors.add_row("all", "", str(int((looked >= 0).sum())), str(int(measured.sum())),
                        str(int(missed.sum())), style="bold")
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


def study_progress(label: str) -> Any:
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


def print_links(logs: Sequence[Any]) -> None:
    """One line on what the links did over a run's decisions (:class:`DecisionLog` s)."""
    import numpy as np

    total = {k: sum(getattr(log, k) for log in logs)
             for k in ("sent", "delivered", "lost", "out_of_range", "in_flight")}
    rounds = np.array([log.rounds for log in logs], dtype=float)
    failed = sorted({i for log in logs for i in log.failed})
    share = total["lost"] / total["sent"] if total["sent"] else 0.0
    rounds_text = (f"median {np.median(rounds):g}, max {rounds.max():g}" if rounds.size
                   else "-")
    print(f"links: {len(logs)} decisions, {total['sent']} messages sent, "
          f"{total['delivered']} delivered, {total['lost']} lost ({share:.1%}), "
          f"{total['out_of_range']} out of range, {total['in_flight']} in flight at a "
          f"decision's end; rounds per decision {rounds_text}; failed agents: "
          f"{', '.join(map(str, failed)) if failed else 'none'}")
