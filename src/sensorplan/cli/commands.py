"""The commands whose work is more than one library call: ``sensorplan grid`` and
``sensorplan replay`` (progress, signals, what is written and said)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from ..study.replay import Replay


def grid_command(path: Path, out: Path | None, workers: int | None,
                 scheduler: str | None) -> int:
    """``sensorplan grid``: load, run with a progress report on stderr, say what was done;
    the exit status (130 when interrupted, 143 when terminated)."""
    from ..study.execution import default_workers
    from ..study.grid import load_grid
    from ..study.grid_run import GridInterrupted, run_grid
    from .console import study_progress
    from .guards import Sigterm

    grid = load_grid(path)
    if workers is not None and workers < 1:
        raise ConfigError("--workers", f"must be an integer >= 1, got {workers}")
    out = out if out is not None else Path("runs") / path.stem
    label = f"grid {path.stem} ({len(grid.cells)} cells)"
    parallel = (workers or default_workers()) if scheduler in (None, "local") else 1
    term = Sigterm()
    try:
        with term, study_progress(label, parallel) as progress:
            res = run_grid(grid, out, workers=workers, scheduler=scheduler,
                           progress=progress)
    except GridInterrupted as exc:
        sys.stdout.flush()
        sys.stderr.write(f"interrupted in cell {exc.cell}: {exc.done} of {exc.total} (run, "
                         f"method) pairs are saved in {out}; run the same command again to "
                         "resume\n")
        return 143 if term.fired else 130
    if res.ran == 0:
        print(f"{out}: grid already complete ({len(grid.cells)} cells, {res.total} (run, "
              "method) pairs); nothing to run")
    else:
        print(f"{out}: ran {res.ran} of {res.total} (run, method) pairs in "
              f"{len(grid.cells)} cells in {res.wall:.1f} s; one study directory per cell")
    print(f"next: sensorplan report {out}")
    return 0


def replay_command(study_dir: Path, run: int, method: str, out: Path | None, animate: bool,
                   animation_format: str) -> Replay:
    """``sensorplan replay``: check the request and the output folder, re-simulate, write
    ``episode.npz``, ``episode.png`` (and the animation), print the run's summary and
    whether it reproduces the stored run (a warning on stderr if it does not).

    Raises
    ------
    ConfigError
        Bad ``DIR``, ``--run``, ``--method``, ``--out`` or ``--animation-format``, found
        before the simulation starts.
    """
    from types import SimpleNamespace

    from ..config.files import ensure_out_dir
    from ..study.replay import check_request, replay_dir_name, replay_run
    from .console import print_summary
    from .guards import animate_drawable, plot_drawable, writing

    if animate:
        from ..figures.animation import check_format

        check_format(animation_format)
    check_request(study_dir, run, method)
    target = out if out is not None else study_dir / "replay" / replay_dir_name(run, method)
    ensure_out_dir(target)                      # before the simulation, not after it
    rep = replay_run(study_dir, run, method)
    npz, png = target / "episode.npz", target / "episode.png"
    scan = rep.study.scenario.scan
    with writing(target):          # a full disk or lost permissions: one line naming --out
        written = [npz, png, rep.episode.save(npz)]
        if scan is not None:
            # The run's figures draw platforms; a scan has none.
            written.remove(png)
            sys.stderr.write(f"note: no episode.png or animation for the {scan} scan (the "
                             "run figures draw platforms; it has none)\n")
        else:
            plot_drawable(rep.episode, rep.study.scenario, png)
        if animate and scan is None:
            written.append(animate_drawable(rep.episode, rep.study.scenario,
                                            target / f"episode.{animation_format}"))
    cfg = SimpleNamespace(scenario=rep.study.scenario, settings=rep.method.settings,
                          seed=f"{rep.study.seed}, run {run}")
    print_summary(rep.episode, cfg, written)
    if rep.damaged is not None:
        print(f"run {run} of {method!r} is damaged in {study_dir}: nothing to compare")
    elif rep.reproduced is None:
        print(f"run {run} of {method!r} is not stored in {study_dir} yet: nothing to compare")
    elif rep.reproduced:
        print(f"identical to the stored run {run} of {method!r} (errors, estimates, NEES, "
              "sensor poses and looks)")
    else:
        worst = max(rep.differences, key=lambda k: rep.differences[k])
        sys.stdout.flush()
        sys.stderr.write(f"warning: the replay differs from the stored run (largest: "
                         f"{worst} by {rep.differences[worst]:.3g}); was the study run "
                         "with another sensorplan version? (see DIR/meta.json)\n")
    return rep
