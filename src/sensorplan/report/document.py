"""The report of a study: PNG figures, one self-contained HTML page, a markdown summary.

Everything is computed from the study directory's files alone (``config.resolved.json``,
``meta.json`` and the tidy tables) with the statistics of :mod:`sensorplan.study.metrics`;
this package only draws (:mod:`.figures`) and formats (this module). The HTML page embeds
its figures as base64 ``data:`` URIs, so it opens from disk with no network and can be
mailed as one file. The definitions of every number are in docs/studies.md.
"""

from __future__ import annotations

import base64
import html
import math
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..simulation.settings import all_settings
from ..study.lifespan import study_has_sets
from ..study.metrics import (DIVERGED_THRESHOLD, LOST_THRESHOLD, consistency,
                             gospa_over_time, gospa_run_metrics, gospa_summary, kinds_with_all,
                             nees_over_time, paired_differences, planning_summary, references,
                             rmse_over_time, run_metrics, sensing_summary, set_methods, summary)
from ..study.model import Method
from ..study.storage import StudyTables, load_study_dir
from .figures import FIGURES, draw_figures
from .headline import SMALL_SAMPLE, headline, headline_paragraphs, results_link
from .search import SEARCH_FIGURES, draw_search_figures, search_section


@dataclass
class ReportFiles:
    """What :func:`write_report` wrote."""

    html: Path
    markdown: Path
    figures: dict[str, Path] = field(default_factory=dict)
    complete: bool = True
    runs: int = 0


def _f(v: float, digits: int = 1) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _ci(mean: float, lo: float, hi: float, digits: int = 1, pct: bool = False) -> str:
    k = 100.0 if pct else 1.0
    unit = " %" if pct else ""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"{_f(k * mean, digits)}{unit}"
    return f"{_f(k * mean, digits)} [{_f(k * lo, digits)}, {_f(k * hi, digits)}]{unit}"


def _setting_text(m: Method, path: str) -> str:
    value: Any = m.settings
    for part in path.split("."):
        value = getattr(value, part)
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, tuple):
        return str(list(value)).replace("[", "(").replace("]", ")")
    return str(value)


class _Doc:
    """Blocks rendered both as markdown and as HTML."""

    def __init__(self) -> None:
        self.blocks: list[tuple[str, Any]] = []

    def h(self, level: int, text: str) -> None:
        self.blocks.append(("h", (level, text)))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, header: list[str], rows: list[list[str]], caption: str = "") -> None:
        self.blocks.append(("table", (header, rows, caption)))

    def figure(self, name: str, path: Path, caption: str | None = None) -> None:
        """A figure with its caption (default: the study figure's, :data:`FIGURES`)."""
        self.blocks.append(("figure", (name, path, caption or FIGURES[name])))

    def headline(self, paragraphs: list[str]) -> None:
        """The boxed summary at the top of the page."""
        self.blocks.append(("headline", paragraphs))

    def toc(self) -> None:
        """A table of contents of the level-2 headings (wherever they are added)."""
        self.blocks.append(("toc", None))

    def _sections(self) -> list[str]:
        return [b[1] for kind, b in self.blocks if kind == "h" and b[0] == 2]

    def markdown(self) -> str:
        out: list[str] = []
        for kind, b in self.blocks:
            if kind == "h":
                out.append("#" * b[0] + " " + b[1])
            elif kind == "p":
                out.append(b)
            elif kind == "headline":
                out.append("\n>\n".join("> " + text for text in b))
            elif kind == "toc":
                out.append("**Contents:** " + " \u00b7 ".join(
                    f"[{t}](#{slug(t)})" for t in self._sections()))
            elif kind == "table":
                header, rows, caption = b
                if caption:
                    out.append(f"*{caption}*\n")
                esc = [[c.replace("|", "\\|") for c in r] for r in [header] + rows]
                out.append("| " + " | ".join(esc[0]) + " |")
                out.append("|" + "|".join("---" if i == 0 else "--:"
                                          for i in range(len(header))) + "|")
                out += ["| " + " | ".join(r) + " |" for r in esc[1:]]
            elif kind == "figure":
                name, path, caption = b
                out.append(f"![{caption}]({path.name})\n\n*{caption}*")
            out.append("")
        return "\n".join(out)

    def html(self, title: str) -> str:
        body: list[str] = []
        for kind, b in self.blocks:
            if kind == "h":
                anchor = f' id="{slug(b[1])}"' if b[0] == 2 else ""
                body.append(f"<h{b[0]}{anchor}>{html.escape(b[1])}</h{b[0]}>")
            elif kind == "p":
                body.append(f"<p>{_inline(b)}</p>")
            elif kind == "headline":
                body.append('<section id="headline" class="headline">'
                            + "".join(f"<p>{_inline(text)}</p>" for text in b) + "</section>")
            elif kind == "toc":
                items = "".join(f'<li><a href="#{slug(t)}">{html.escape(t)}</a></li>'
                                for t in self._sections())
                body.append(f'<nav id="contents" class="toc"><strong>Contents</strong>'
                            f"<ol>{items}</ol></nav>")
            elif kind == "table":
                header, rows, caption = b
                cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
                head = "".join(f"<th>{html.escape(c)}</th>" for c in header)
                trs = "".join("<tr>" + "".join(
                    f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
                body.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{trs}"
                            "</tbody></table>")
            elif kind == "figure":
                name, path, caption = b
                data = base64.b64encode(path.read_bytes()).decode("ascii")
                body.append(f'<figure id="fig-{name}"><img src="data:image/png;base64,{data}" '
                            f'alt="{html.escape(caption)}"><figcaption>'
                            f"{html.escape(caption)}</figcaption></figure>")
        return _HTML.format(title=html.escape(title), body="\n".join(body))


def _inline(text: str) -> str:
    """Escape, then render markdown `code`, **bold** and [link](href) spans."""
    import re

    t = html.escape(text)
    t = re.sub(r"`([^`]+)`", r"<code>\1</code>", t)
    t = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)",
               r'<a href="\2">\1</a>', t)                 # both already escaped
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)


def slug(text: str) -> str:
    """Anchor of a heading, as GitHub spells it (lower case, punctuation dropped, spaces
    as hyphens), so that the contents links work in the HTML page and in summary.md."""
    import re

    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


_HTML = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
body {{ font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1150px;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }}
h1 {{ font-size: 1.6em; }} h2 {{ margin-top: 1.8em; border-bottom: 1px solid #ddd; }}
table {{ border-collapse: collapse; margin: 0.8em 0 1.2em; font-size: 0.9em; }}
caption {{ caption-side: top; text-align: left; font-style: italic; padding-bottom: 0.3em; }}
th, td {{ border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }}
th:first-child, td:first-child {{ text-align: left; }}
thead th {{ background: #f3f3f3; }}
tbody tr:nth-child(even) {{ background: #fafafa; }}
figure {{ margin: 1.2em 0; }} figure img {{ max-width: 100%; height: auto; }}
figcaption {{ font-size: 0.9em; color: #444; }}
code {{ background: #f3f3f3; padding: 0 0.2em; }}
.headline {{ background: #f4f7fb; border-left: 4px solid #3a5a98; padding: 0.4em 1em;
            margin: 1em 0; }}
.headline p {{ margin: 0.5em 0; }}
.toc {{ font-size: 0.95em; margin: 1em 0 1.5em; }}
.toc ol {{ margin: 0.3em 0; padding-left: 1.6em; columns: 2; }}
</style>
</head>
<body>
{body}
</body>
</html>
"""


# ------------------------------------------------------------------------------ report


def write_report(study_dir: str | Path, out: str | Path | None = None) -> ReportFiles:
    """Write ``report.html``, ``summary.md`` and the PNG figures of a study directory.

    Parameters
    ----------
    study_dir : path
        Written by :func:`sensorplan.study.run_study` (finished or not: an unfinished
        study is reported on the runs every method has finished).
    out : path, optional
        Report directory (default ``study_dir/report``).

    Returns
    -------
    ReportFiles

    Raises
    ------
    ConfigError
        ``study_dir`` is not a study directory or holds no finished run.
    """
    study_dir = Path(study_dir)
    t = load_study_dir(study_dir)
    out = Path(out) if out is not None else study_dir / "report"
    out.mkdir(parents=True, exist_ok=True)

    metrics = run_metrics(t)
    rmse = summary(metrics, "rmse")
    lost = summary(metrics, "lost_share")
    # A t-interval of a share can leave [0, 1]; show it clipped (the share cannot).
    lost[["mean_lo", "mean_hi"]] = lost[["mean_lo", "mean_hi"]].clip(0.0, 1.0)
    # A study of changing sets is judged by GOSPA: a multi-target tracker's RMSE covers only
    # the target-steps with an assigned track, so it leaves out the targets it missed.
    column = "gospa" if study_has_sets(t.study) else "rmse"
    judged = gospa_run_metrics(t) if column == "gospa" else metrics
    diffs = paired_differences(judged, t.study, column=column)
    plan = planning_summary(t)
    sensing = sensing_summary(t)
    honest = consistency(t)
    gospa = gospa_summary(t)
    figs = draw_figures(t, out, {"rmse": rmse, "lost": lost, "diffs": diffs, "plan": plan,
                                 "curves": rmse_over_time(t), "nees": nees_over_time(t),
                                 "gospa": gospa_over_time(t), "quantity": column.upper()})
    figs.update(draw_search_figures(t, out))

    top = headline(t.study, judged,
                   summary(judged, "gospa") if column == "gospa" else rmse, diffs, column)
    lines = headline_paragraphs(top, results_link(out))
    single = _single_runs(judged, t, top)
    worst = next((row[3].split()[1] for row in single if row[0] == top.best), None)
    example = (f"sensorplan replay {shlex.quote(str(study_dir))} --run {worst} --method "
               f"{shlex.quote(top.best)}") if worst is not None else None
    doc = _document(t, rmse, lost, diffs, plan, sensing, figs, honest, lines, single,
                    example, column)
    _gospa_section(doc, gospa, figs, _gospa_c(t.study))
    search_section(doc, t, figs)
    title = f"sensorplan study report: {study_dir.name}"
    md = out / "summary.md"
    page = out / "report.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    page.write_text(doc.html(title), encoding="utf-8")
    return ReportFiles(page, md, figs, t.complete, len(t.runs_done))


def _gospa_c(study: Any) -> float:
    """The study's GOSPA cut-off (m): a study-wide setting, the same for every method."""
    return float(study.methods[0].settings.gospa_c)


def _gospa_section(doc: _Doc, gospa: Any, figs: dict[str, Path], c: float) -> None:
    """The multi-target error: GOSPA per method and its parts, with the cut-off ``c`` (m)."""
    doc.h(2, "GOSPA (the reported tracks against the live targets)")
    doc.p(f"GOSPA (alpha = 2, p = 2, cut-off c = {c:g} m) compares the set of "
          "reported tracks with the set of live targets at every step: its square is the "
          "localisation error of the assigned pairs plus c^2/2 for each missed target and "
          "for each false track. Per run its mean over the steps; across runs the mean with "
          "its 95 % t-interval and the median with its 95 % interval; the parts are the "
          "mean contributions to GOSPA^2 (m^2), false tracks the mean per step.")
    rows = [[str(r.method), _ci(r.mean, r.lo, r.hi), _ci(r.median, r.median_lo, r.median_hi),
             _f(r.localisation), _f(r.missed), _f(r.false), _f(r.false_tracks, 2)]
            for r in gospa.itertuples()]
    doc.table(["method", "GOSPA mean (m)", "median", "localisation", "missed", "false",
               "false tracks"], rows, caption=_caption("per run", gospa))
    doc.figure("gospa_time", figs["gospa_time"])
    if "gospa_parts_time" in figs:                      # a study that searches
        doc.figure("gospa_parts_time", figs["gospa_parts_time"],
                   SEARCH_FIGURES["gospa_parts_time"])
    if "gospa_runs" in figs:
        doc.figure("gospa_runs", figs["gospa_runs"])


def _small(rows: Any) -> bool:
    """Whether summary rows come from few runs: the metrics' ``small_sample`` flag when
    they carry one, else fewer than :data:`~.headline.SMALL_SAMPLE` runs."""
    if not len(rows):
        return False
    if "small_sample" in rows:
        return bool(rows["small_sample"].astype(bool).any())
    return bool((rows["n"] < SMALL_SAMPLE).any())


def _caption(label: str, rows: Any) -> str:
    if not _small(rows):
        return label
    return f"{label} (n = {int(rows['n'].min())} runs < {SMALL_SAMPLE}: intervals unreliable)"


def _single_runs(metrics: Any, t: StudyTables, top: Any) -> list[list[str]]:
    """Per method: its best, median and worst run by RMSE over the headline's targets (by
    mean GOSPA when the headline judges by it)."""
    m = metrics[metrics["kind"].astype(str) == top.kind]
    column = top.metric
    rows = []
    for name in t.study.method_names:
        g = m[m["method"] == name].sort_values([column, "run"], kind="stable")
        if not len(g):
            continue
        runs, values = g["run"].to_numpy(), g[column].to_numpy(float)
        mid = (len(g) - 1) // 2
        rows.append([name] + [f"run {int(runs[k])} ({values[k]:.1f} m)"
                              for k in (0, mid, len(g) - 1)])
    return rows


def population_text(scenario: Any) -> str:
    """The scenario's targets in words: how many, of which kinds, and how they come and go
    (with births, ``targets`` are the templates born targets take, not a count)."""
    kinds = scenario.target_kinds
    counts = ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds))
    if scenario.scripted is not None:
        return f"the {scenario.scripted} truth (targets born and dying as its source scripts)"
    if scenario.known_targets:
        return f"{len(scenario.targets)} targets ({counts})"
    where = {"edges": "at the map's edges", "uniform": "anywhere on the map"}
    births = ("no births" if scenario.births == "none" else
              f"{scenario.birth_rate:g} births a step {where.get(scenario.births, '')}")
    return (f"{scenario.n_initial} targets at the start, {births}, survival probability "
            f"{scenario.survival_probability:g} a step; targets take {len(kinds)} "
            f"template{'s' if len(kinds) != 1 else ''} ({counts})")


def _document(t: StudyTables, rmse: Any, lost: Any, diffs: Any, plan: Any, sensing: Any,
              figs: dict[str, Path], honest: Any, top: list[str],
              single: list[list[str]], example: str | None, column: str = "rmse") -> _Doc:
    study, meta = t.study, t.meta
    sets = set(set_methods(study))

    def name_of(method: str) -> str:
        """A method's name, marked where its errors are those of assigned tracks."""
        return f"{method} (assigned tracks)" if method in sets else method
    doc = _Doc()
    doc.h(1, "Study report" + (f": {study.description}" if study.description else ""))
    doc.headline(top)
    sessions = meta.get("sessions", [])
    wall = meta.get("wall_seconds")
    versions = meta.get("versions", {})
    facts = [f"{len(t.runs_done)} paired runs" + ("" if t.complete else
                                                  f" of {study.runs} (**study unfinished**)"),
             f"{study.steps} steps of {study.scenario.dt:g} s", f"seed {study.seed}",
             f"scenario: {study.scenario_source}",
             f"{population_text(study.scenario)}, {len(study.scenario.sensors)} sensors"]
    if t.methods_missing:
        facts.append(f"methods not run yet (left out): {', '.join(t.methods_missing)}")
    doc.p("; ".join(facts) + ".")
    if wall is not None:
        ex_names = ", ".join(dict.fromkeys(s.get("executor", "?") for s in sessions))
        doc.p(f"Computed in {wall:.0f} s wall time over {len(sessions)} session(s) "
              f"({ex_names}) on {meta.get('platform', '?')} with {meta.get('cpu_count', '?')} "
              f"CPUs; sensorplan {versions.get('sensorplan', '?')}, numpy "
              f"{versions.get('numpy', '?')}, Python {versions.get('python', '?')}"
              + (f", git {meta['git']}" if meta.get("git") else "") + ".")
    doc.toc()

    doc.h(2, "Methods")
    refs = references(study)
    # One column per method setting that differs between methods (planner settings aside),
    # from their declarations; the settings every method shares are listed once below. The
    # search settings (and the reward, its unreported mode, find tail and track existence,
    # which only search uses) only when a method searches (they change nothing otherwise).
    searching = any(m.settings.search == "on" for m in study.methods)
    columns = [(path, s.label or f.name) for _, path, f, s in all_settings()
               if s.section != "run" and f.name != "planner_params"
               and (searching or f.name not in ("search", "search_sectors", "reward",
                                                "unreported", "find_tail",
                                                "track_existence"))]
    text = {path: [_setting_text(m, path) for m in study.methods] for path, _ in columns}
    varying = [(p, label) for p, label in columns if len(set(text[p])) > 1 or p == "planner"]
    shared = [(p, label) for p, label in columns if (p, label) not in varying]
    doc.table(["method", *(label for _, label in varying), "vs myopic", "vs random"],
              [[m.name, *(text[p][n] for p, _ in varying),
                refs[m.name]["myopic"] or "–", refs[m.name]["random"] or "–"]
               for n, m in enumerate(study.methods)])
    if shared:
        doc.p("Every method: " + "; ".join(f"{label} {text[p][0]}" for p, label in shared)
              + ".")
    doc.p("Every method runs on the same paired runs: identical true trajectories, initial "
          "estimates, sensor starts and measurement noise streams (common random numbers).")
    doc.figure("scenario", figs["scenario"])

    doc.h(2, "Position RMSE and lost tracks")
    doc.p("RMSE of a run (per target kind) = sqrt(mean over steps 1..S and the kind's targets "
          "of the squared position error). Across runs: mean [95 % t-interval] and median "
          "[95 % distribution-free order-statistic interval]. Lost: share of target-steps with "
          f"error > {LOST_THRESHOLD:g} m, mean across runs [95 % t-interval, clipped to "
          "[0, 100] %].")
    if sets:
        doc.p("A multi-target tracker (marked \"assigned tracks\") has no track per target: "
              "its errors are those of the track GOSPA assigns to each live target, so its "
              "RMSE is over the target-steps that have one, and a lost target-step is one "
              "without one (GOSPA's missed part; an assigned track lies within the cut-off, "
              "so the error rule would count none). GOSPA below judges it with the rest.")
    for kind in kinds_with_all(study):
        r = rmse[rmse["kind"] == kind].set_index("method")
        lo = lost[lost["kind"] == kind].set_index("method")
        rows = []
        for name in study.method_names:
            if name not in r.index:
                continue
            a, b = r.loc[name], lo.loc[name]
            rows.append([name_of(name), _ci(a["mean"], a["mean_lo"], a["mean_hi"]),
                         _ci(a["median"], a["median_lo"], a["median_hi"]),
                         _ci(b["mean"], b["mean_lo"], b["mean_hi"], pct=True)])
        label = f"{kind} targets" if kind != "all" else "all targets"
        doc.table(["method", "RMSE mean (m)", "RMSE median (m)", "lost target-steps"], rows,
                  caption=_caption(label, r))
    doc.figure("rmse_time", figs["rmse_time"])
    doc.figure("rmse_overall", figs["rmse_overall"])
    doc.figure("lost_share", figs["lost_share"])

    doc.h(2, "Paired differences")
    quantity = "GOSPA" if column == "gospa" else "RMSE"
    if column == "gospa":
        doc.p("This study has changing sets (a multi-target tracker, or targets born and "
              "dying), so methods are compared by GOSPA, which charges missed targets and "
              "false tracks; RMSE would leave out what a multi-target tracker misses. Per "
              "run: the mean GOSPA over steps 1..S of the method minus that of the reference "
              "on the same run. Mean [95 % paired t-interval], median [95 % order-statistic "
              "interval], and the share of runs in which the method had the lower GOSPA. An "
              "interval entirely below zero means the method is better with 95 % "
              "confidence.")
    else:
        doc.p("Per run: RMSE of the method minus RMSE of the reference on the same run. Mean "
              "[95 % paired t-interval], median [95 % order-statistic interval], and the "
              "share of runs in which the method had the lower RMSE. An interval entirely "
              "below zero means the method is better with 95 % confidence.")
    for against in ("myopic", "random"):
        d = diffs[diffs["against"] == against] if len(diffs) else diffs
        rows = [[r.method, r.reference, str(r.kind), _ci(r.mean, r.mean_lo, r.mean_hi),
                 _ci(r.median, r.median_lo, r.median_hi), f"{100 * r.better_share:.0f} %"]
                for r in d.itertuples()] if len(d) else []
        if rows:
            doc.table(["method", "reference", "kind", f"\u0394 {quantity} mean (m)",
                       f"\u0394 {quantity} median (m)", "runs better"], rows,
                      caption=_caption(f"against {against}", d))
        else:
            doc.p(f"No method has a {against} reference in this study.")
    doc.figure("paired_differences", figs["paired_differences"],
               None if column != "gospa" else
               "Paired differences of the run's mean GOSPA (method minus reference, run by "
               "run) against the myopic planner and against random with the same tracker; "
               "mean with its 95 % paired t-interval. Left of zero: the method tracks better.")

    doc.h(2, "Track consistency")
    doc.p("Is each filter honest about its own error? NEES = e^T P^-1 e of the full state "
          "(position and velocity) is chi-square with 4 degrees of freedom for a consistent "
          "filter: its average (ANEES) is 4, inside the 95 % chi-square band for the number "
          f"of samples, and {100 * (1 - 0.99):.0f} % of target-steps exceed 13.28 (the 99 % "
          "point). Restarts: tracks restarted from a detection outside their gate; map "
          "corrections: tracks truncated to the known map (both per run). Diverged runs: "
          f"largest position error above {DIVERGED_THRESHOLD:g} m.")
    for kind in kinds_with_all(study):
        h = honest[honest["kind"] == kind]
        rows = [[name_of(str(r.method)), f"{r.anees:.2f} [{r.band_lo:.2f}, {r.band_hi:.2f}]",
                 f"{r.median_nees:.2f}", f"{100 * r.high_share:.1f} %", f"{r.restarts:.2f}",
                 f"{r.map_corrections:.1f}",
                 "–" if str(r.method) in sets else f"{r.diverged} of {r.runs}"]
                for r in h.itertuples()]
        label = f"{kind} targets" if kind != "all" else "all targets"
        doc.table(["method", "ANEES [95 % band]", "median NEES", "NEES > 13.28",
                   "restarts per run", "map corrections per run", "diverged runs"], rows,
                  caption=label)
    doc.figure("nees_time", figs["nees_time"])

    doc.h(2, "Single runs")
    doc.p("Each method's best, median and worst run by "
          + ("mean GOSPA" if column == "gospa" else "position RMSE over "
             + ("all targets" if len(kinds_with_all(study)) > 1 else "the targets"))
          + ". To see one (a map with the tracks, looks and misses, an assignment "
          "timeline, errors over time and an animation), re-simulate it exactly from this "
          "study: `sensorplan replay DIR --run R --method NAME`"
          + (f"; for the worst run of the best method: `{example}`" if example else "")
          + ".")
    doc.table(["method", "best run", "median run", "worst run"], single)

    doc.h(2, "Planning time and convergence")
    rows = []
    for r in plan.itertuples():
        conv = ("–" if not math.isfinite(r.converged_share)
                else f"{100 * r.converged_share:.1f} %")
        sweeps = "–" if not math.isfinite(r.sweeps_mean) else \
            f"{r.sweeps_mean:.2f} (max {r.sweeps_max:.0f})"
        rows.append([str(r.method), str(r.decisions), _f(r.mean_ms, 2), _f(r.median_ms, 2),
                     _f(r.p90_ms, 2), _f(r.max_ms, 1), _f(r.seconds_per_run, 2), conv,
                     sweeps, _f(r.phi_mean, 2)])
    doc.table(["method", "decisions", "mean ms", "median ms", "p90 ms", "max ms",
               "s per run", "converged", "sweeps", "mean Phi (nats)"], rows,
              caption="planning time is wall-clock time of the planner call (depends on "
                      "the machine and its load)")
    for name in ("planning_time", "convergence"):
        if name in figs:                      # none for a scan study: nothing is planned
            doc.figure(name, figs[name])
    if "horizon" in figs:
        doc.figure("horizon", figs["horizon"])

    doc.h(2, "Sensing")
    doc.table(["method", "looks per sensor-step", "measurements per sensor-step",
               "looks that missed"],
              [[str(r.method), f"{r.look_share:.2f}", f"{r.measurements_per_sensor_step:.2f}",
                "–" if not math.isfinite(r.miss_share) else f"{100 * r.miss_share:.1f} %"]
               for r in sensing.itertuples()],
              caption="over sensor-steps 1..S; a missed look points at a target that is "
                      "truly outside the field of view")
    doc.p("Files: `config.resolved.json` (the study with every default), `meta.json` "
          "(versions, seed, wall time), `steps.parquet`, `decisions.parquet`, "
          "`sensors.parquet` (tidy tables); regenerate this report with "
          "`sensorplan report DIR`.")
    return doc
