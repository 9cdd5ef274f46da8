"""Monte Carlo studies: paired runs, resumable execution, tidy tables, statistics.

A :class:`Study` runs every :class:`Method` on the same ``runs`` paired runs (common random
numbers); :func:`run_study` executes the missing (run, method) pairs and writes a study
directory that :func:`load_study_dir` reads back. The package's modules:

- :mod:`.model`: :class:`Study`, :class:`Method` and the resolved configuration;
- :mod:`.file`: study files (TOML) -> :class:`Study`;
- :mod:`.execution`: one (run, method) as a task, the executors, :func:`run_study`;
- :mod:`.storage`: the study directory (atomic parts, lock, metadata, reading back);
- :mod:`.tables`: the tidy tables of an episode;
- :mod:`.metrics`: RMSE, lost tracks, track consistency (NEES), intervals, paired
  differences, summaries;
- :mod:`.demo`: the built-in demo study.
"""

from .demo import DEMO_STUDIES, DEMO_STUDY, PAPER_DEMO_STUDY, demo_study
from .execution import StudyInterrupted, StudyRun, TaskResult, default_workers, run_study, \
    run_task
from .file import load_study, parse_study, study_from_dict
from .metrics import (DIVERGED_THRESHOLD, LEVEL, LOST_THRESHOLD, METRIC_RANGES, NEES_HIGH,
                      SMALL_SAMPLE, consistency,
                      episode_consistency, episode_errors, horizon_groups, kinds_with_all,
                      median_interval, nees_band, nees_over_time, paired_differences,
                      planning_summary, references, rmse_over_time, run_metrics,
                      sensing_summary, summary, t_interval)
from .model import FORMAT, Method, Study
from .storage import StudyTables, consolidate, done_tasks, load_study_dir, part_path
from .tables import TABLE_DOC, TABLES, episode_tables

__all__ = ["DEMO_STUDIES", "DEMO_STUDY", "PAPER_DEMO_STUDY", "DIVERGED_THRESHOLD", "FORMAT",
           "LEVEL", "LOST_THRESHOLD",
           "METRIC_RANGES", "SMALL_SAMPLE",
           "NEES_HIGH", "Method", "Study", "consistency", "episode_consistency", "nees_band",
           "nees_over_time",
           "StudyInterrupted", "StudyRun", "StudyTables", "TABLES", "TABLE_DOC", "TaskResult",
           "consolidate", "default_workers", "demo_study", "done_tasks", "episode_errors",
           "episode_tables", "horizon_groups", "kinds_with_all", "load_study",
           "load_study_dir", "median_interval", "paired_differences", "parse_study",
           "part_path", "planning_summary", "references", "rmse_over_time", "run_metrics",
           "run_study", "run_task", "sensing_summary", "study_from_dict", "summary",
           "t_interval"]
