"""What the command line prints: progress bars and the summary tables of a run (rich).

Imported by the commands that print them, so that ``sensorplan --help`` and
``sensorplan plan`` do not load rich's tables.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..simulation.settings import all_settings

#: A plain progress line (stderr not a terminal) at most this often, besides every 10 %.
LINE_SECONDS = 60.0
#: No plain progress line before this many seconds (but the last): a run that fails at
#: once, or finishes at once, prints no progress.
FIRST_LINE_SECONDS = 5.0


class PlainProgress:
    """Progress as plain lines on a non-terminal stderr (a log file, a pipe).

    A line about every 10 % of the work or every :data:`LINE_SECONDS`, and at the end if
    any came before; none before the first unit of work is done nor in the first
    :data:`FIRST_LINE_SECONDS`, so that a run failing (or done) early prints nothing but
    its error line (or its results). The ETA leaves out
    the start-up (worker processes, compiled kernels): it extrapolates from the time since
    the first unit finished once ``parallel`` more have, before that from the work's own
    measured time per unit (``seconds``, reported by the workers).

    Parameters
    ----------
    label : str           what is running (the line's prefix)
    unit : str            what is counted ("steps"; "" for none)
    parallel : int        units running at once (worker processes)
    write : callable      writes one line (default: to stderr)
    clock : callable      monotonic seconds (tests pass their own)
    """

    def __init__(self, label: str, unit: str, parallel: int = 1,
                 write: Any = None, clock: Any = None) -> None:
        import time

        self.label, self.unit, self.parallel = label, unit, max(1, int(parallel))
        self.write = write or _stderr_line
        self.clock = clock or time.perf_counter
        self.start = self.clock()
        self.first: float | None = None       # when the first unit finished
        self.first_done = 0
        self.next_share = 0.0
        self.last = self.start
        self.seconds: list[float] = []
        self.lines = 0                        # lines written

    def restart(self) -> None:
        """Set the clock's origin (the work starts now)."""
        self.start = self.last = self.clock()

    def __call__(self, done: int, total: int, already: int = 0,
                 seconds: float | None = None) -> None:
        now = self.clock()
        if seconds is not None:
            self.seconds.append(float(seconds))
        if done <= 0 or total <= 0:
            return
        if self.first is None:
            self.first, self.first_done = now, done
        due = done / total + 1e-12 >= self.next_share or now - self.last >= LINE_SECONDS
        early = now - self.start < FIRST_LINE_SECONDS
        if done == total and not self.lines:
            return                      # quick work: no progress was shown, none is due
        if (not due or early) and done != total:
            return
        self.lines += 1
        self.next_share = done / total + 0.1
        self.last = now
        line = (f"{self.label}: {done}/{total}{' ' + self.unit if self.unit else ''} done"
                + (f" ({already} already done before)" if already else "")
                + f", {now - self.start:.0f} s elapsed")
        eta = self.eta(done, total, now)
        if done < total and eta is not None:
            line += f", ETA {eta:.0f} s"
        self.write(line)

    def eta(self, done: int, total: int, now: float) -> float | None:
        """Seconds left, without the start-up (see the class docstring)."""
        left = total - done
        if left <= 0:
            return 0.0
        if done - self.first_done >= self.parallel and self.first is not None:
            rate = (now - self.first) / (done - self.first_done)   # s per unit, warm
            return left * rate
        if self.seconds:
            per_unit = sum(self.seconds) / len(self.seconds)
            return left * per_unit / min(self.parallel, left)
        return None


def _stderr_line(line: str) -> None:
    import sys

    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def run_with_progress(run_episode: Any, cfg: Any) -> Any:
    """``run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=...)`` with progress on
    stderr: a bar on a terminal, plain lines otherwise (:class:`PlainProgress`)."""
    from rich.console import Console
    from rich.progress import (
                               BarColumn,
                               MofNCompleteColumn,
                               Progress,
                               TextColumn,
                               TimeElapsedColumn,
                               TimeRemainingColumn,
                               )

    console = Console(stderr=True)
    if not console.is_terminal:
        lines = PlainProgress("simulating", "steps")

        def plain(done: int, total: int) -> None:
            lines(done, total)

        return run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=plain)
    columns = (TextColumn("simulating"), BarColumn(), MofNCompleteColumn(),
               TextColumn("steps"), TimeElapsedColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task("simulate", total=cfg.settings.steps)

        def report(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        return run_episode(cfg.scenario, cfg.settings, cfg.seed, progress=report)


#: Tables list every target and sensor up to this many; beyond it the first few and a note.
MAX_ROWS = 20


def planner_title(planner: str) -> str:
    """How a run's header names the planner given as ``planner``: its ``name``, as the plan
    file's ``planner`` key says it, followed by its ``module:Class`` when it is not built in
    (``midband (myplanner:MidBandNearest)``)."""
    from ..errors import ConfigError
    from ..planners.registry import planner_class, planner_label

    try:
        cls = planner_class(planner)
    except ConfigError:                 # not importable here: the name the run was given
        return planner
    label = planner_label(cls)
    return label.replace(repr(cls.name), cls.name, 1)


def print_summary(episode: Any, cfg: Any, written: Sequence[Path]) -> None:
    import numpy as np
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from ..study.metrics import LOST_THRESHOLD, NEES_HIGH, episode_consistency, episode_errors

    console = Console()
    s = cfg.settings
    scan = cfg.scenario.scan
    if scan is not None:
        console.print(f"[bold]{escape(scan)} scan[/] (its linear sensor sees the whole map "
                      f"every step; nothing is planned), {s.steps} steps, seed {cfg.seed}",
                      highlight=False)
    else:
        console.print(f"[bold]{escape(planner_title(s.planner))}[/], K = {s.horizon}, "
                      f"e = {s.steps_per_epoch}, {s.execution.upper()}, {s.steps} steps, "
                      f"seed {cfg.seed}", highlight=False)
    # Only the tracker settings that act with the others as they are (no cv q with the IMM,
    # no exit rule where the tracker's map edge turns targets back).
    from ..simulation.run import map_edge

    edge = map_edge(cfg.scenario, s.tracker) if s.tracker.kind != "known" else None
    unused = s.tracker.unused(edge)

    def shown(name: str) -> str:
        value = getattr(s.tracker, name)
        # "scenario" is resolved from the truth: say what it became.
        return f"{value} ({edge})" if name == "map_edge" and value == "scenario" else str(value)

    tracker = ", ".join(f"{meta.label or f.name} {shown(f.name)}"
                        for _, path, f, meta in all_settings()
                        if path.startswith("tracker.") and f.name not in unused)
    counts = s.search_sectors
    sectors = str(counts) if isinstance(counts, int) else "/".join(str(c) for c in counts)
    confirm = ", unreported tracks confirmed" if s.unreported == "confirm" else ""
    tail = f", finds counted {s.find_tail} steps on" if s.find_tail else ""
    resolved = (", looks resolve track existence" if s.track_existence == "resolved"
                else "")
    reward = (f"reward {s.reward} (c = {s.gospa_c:g} m{confirm}{tail}{resolved}), "
              if s.reward == "gospa" else "")
    searching = f"search on ({sectors} sectors), {reward}" if s.search == "on" else ""
    console.print(tracker if scan is not None else
                  f"visibility {s.visibility}, objective {s.objective}, {searching}{tracker}",
                  highlight=False)

    measured = np.asarray(episode.measured)[1:]                # (S, M, N)
    lost_rule = (f"share of steps with error > {LOST_THRESHOLD:g} m"
                 if s.tracker.kind == "known" else
                 f"share of live steps without a track within c = {s.gospa_c:g} m")
    tracks = Table(title="Position error over steps 1..S (m)",
                   caption=f"lost: {lost_rule}; measured: "
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
    from ..study.set_metrics import episode_set_metrics

    sm = episode_set_metrics(episode)
    g = sm.gospa
    console.print(f"GOSPA (c = {s.gospa_c:g} m): mean {g.distance.mean():.1f} m over steps "
                  f"1..S; its parts, mean m^2: localisation {g.localisation.mean():.1f}, "
                  f"missed {g.missed.mean():.1f}, false {g.false.mean():.1f}; false tracks "
                  f"per step {sm.false_tracks.mean():.2f}; targets lost "
                  f"{sm.targets.targets_lost}", highlight=False)
    if scan is not None:
        # One scan a step, no platforms and no decisions: the detections say it all.
        det = np.asarray(episode.detections)[1:, 0]
        fa = np.asarray(episode.false_alarms)[1:, 0]
        console.print(f"scans: {det.size}, detections per scan {det.mean():.1f} (false alarms "
                      f"{fa.mean():.1f}); target detections {int(measured.sum())} of "
                      f"{int(np.asarray(episode.alive)[1:].sum())} live target-steps",
                      highlight=False)
        for path in written:
            console.print(f"wrote {path}", soft_wrap=True, markup=False, highlight=False)
        return

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
                  caption="time: the planner's own time per decision (ms)")
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
    if episode.search_term is not None:
        searched = np.asarray(episode.searched)[1:]            # (S, N)
        # The gospa reward counts the GOSPA bound removed, in m^2.
        unit = "m^2" if cfg.settings.reward == "gospa" else "nats"
        console.print(f"search: {int((searched >= 0).sum())} of {searched.size} sensor-steps "
                      f"looked at a search sector; Phi's search term w mu per decision: mean "
                      f"{stat(np.asarray(episode.search_term), '.3f')} {unit} (mu, the "
                      f"undetected targets a plan expects to find: mean "
                      f"{stat(np.asarray(episode.search_found), '.3f')})", highlight=False)
    for path in written:
        # One path a line, never broken: it is there to be copied.
        console.print(f"wrote {path}", soft_wrap=True, markup=False, highlight=False)


def study_progress(label: str, parallel: int = 1) -> Any:
    """Context manager yielding a ``progress(done, total, already, seconds=None)`` callback
    for :func:`sensorplan.study.run_study`: a bar with ETA on a terminal (removed when the
    study stops, so that an error is the only line left), plain lines otherwise
    (:class:`PlainProgress`; ``parallel``: worker processes, for its first ETA)."""
    from rich.console import Console
    from rich.progress import (
                               BarColumn,
                               MofNCompleteColumn,
                               Progress,
                               TextColumn,
                               TimeElapsedColumn,
                               TimeRemainingColumn,
                               )

    console = Console(stderr=True)

    @contextmanager
    def bar() -> Iterator[Any]:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("(run, method) pairs"), TimeElapsedColumn(),
                   TextColumn("ETA"), TimeRemainingColumn())
        progress = Progress(*columns, console=console, transient=True)
        task = progress.add_task(label, total=None)
        started = False

        def report(done: int, total: int, already: int, seconds: float | None = None
                   ) -> None:
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
        plain = PlainProgress(label, "", parallel)

        def report(done: int, total: int, already: int, seconds: float | None = None
                   ) -> None:
            if done == 0:
                plain.restart()
            plain(done, total, already, seconds)
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


def write_agent_logs(path: Path, episode: Any, logs: Sequence[Any]) -> None:
    """agents.json: the decision steps and each decision's :class:`DecisionLog`."""
    import dataclasses
    import json

    def plain(v: Any) -> Any:
        return v.item() if hasattr(v, "item") else str(v)

    steps = json.dumps([int(s) for s in episode.decision_steps])
    rows = ",\n".join("  " + json.dumps(dataclasses.asdict(log), default=plain) for log in logs)
    path.write_text(f'{{"decision_steps": {steps},\n "decisions": [\n{rows}\n]}}\n',
                    encoding="utf-8")
