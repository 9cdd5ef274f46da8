"""Who lives when: births and deaths of targets, confirmations and deletions of tracks, read
from what a run recorded (numpy only; the figures, the animation and the study tables use it).

A run records which target slots are alive at each step (``Episode.alive``) and the set of
tracks the tracker reported at each step (``track_step``, ``track_label``, ...). From these:

- a target is *born* at step t >= 1 when it is alive at t and was not at t - 1, and *dies*
  at step t >= 1 when it was alive at t - 1 and is not at t (its last position is that of
  t - 1); targets alive at step 0 are the initial ones, not births;
- a track is *confirmed* at the first step >= 1 its label is reported, and *deleted* at the
  step after its last report when that report is before the run's last step (its last
  position is that of the last report); tracks reported at step 0 are the initial ones.

A label that is reported, drops below the report threshold and is reported again is one
track with a gap: it is confirmed once and deleted once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .._types import FloatArray, IntArray
from .set_metrics import set_metrics

if TYPE_CHECKING:  # pragma: no cover
    from ..simulation.episode import Episode
    from .model import Study


@dataclass(frozen=True)
class EventList:
    """Events of one kind, in step order (then by id).

    Attributes
    ----------
    step : (K,) int64    the step the event is shown at
    ident : (K,) int64   the target slot (births, deaths) or the track label
    xy : (K, 2) float64  where: the first position, or the last one before it ended (m)
    """

    step: IntArray
    ident: IntArray
    xy: FloatArray

    def __len__(self) -> int:
        return len(self.step)

    def at(self, t: int) -> IntArray:
        """The ids of the events of step ``t``."""
        lo, hi = np.searchsorted(self.step, [t, t + 1])
        return self.ident[lo:hi]


@dataclass(frozen=True)
class Events:
    """The life events of a run (see the module docstring)."""

    births: EventList
    deaths: EventList
    confirmations: EventList
    deletions: EventList

    def text(self, t: int) -> str:
        """One line naming step ``t``'s events (empty when there are none): ``born T5;
        died T2; confirmed L7; deleted L3``."""
        parts = []
        for name, events, prefix in (("born", self.births, "T"), ("died", self.deaths, "T"),
                                     ("confirmed", self.confirmations, "L"),
                                     ("deleted", self.deletions, "L")):
            ids = events.at(t)
            if len(ids):
                parts.append(f"{name} " + ", ".join(f"{prefix}{int(k)}" for k in ids))
        return "; ".join(parts)


def _event_list(step: npt.ArrayLike, ident: npt.ArrayLike, xy: npt.ArrayLike) -> EventList:
    s = np.asarray(step, dtype=np.int64).reshape(-1)
    k = np.asarray(ident, dtype=np.int64).reshape(-1)
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    order = np.lexsort((k, s))
    return EventList(s[order], k[order], p[order])


def target_events(alive: npt.ArrayLike, truth_xy: npt.ArrayLike) -> tuple[EventList, EventList]:
    """Births and deaths of the target slots.

    Parameters
    ----------
    alive : (S+1, M) bool    which slots hold a live target at each step
    truth_xy : (S+1, M, 2) float    their true positions (m)

    Returns
    -------
    ``(births, deaths)``: a birth at its first live step and position, a death at the first
    step it is gone with its last live position.
    """
    a = np.asarray(alive, dtype=bool)
    xy = np.asarray(truth_xy, dtype=float)[..., :2]
    born = a[1:] & ~a[:-1]                                  # (S, M): step t = index + 1
    died = a[:-1] & ~a[1:]
    bt, bj = np.nonzero(born)
    dt, dj = np.nonzero(died)
    return (_event_list(bt + 1, bj, xy[bt + 1, bj]), _event_list(dt + 1, dj, xy[dt, dj]))


def track_events(track_step: npt.ArrayLike, track_label: npt.ArrayLike,
                 track_xy: npt.ArrayLike, last_step: int) -> tuple[EventList, EventList]:
    """Confirmations and deletions of the reported tracks.

    Parameters
    ----------
    track_step, track_label : (R,) int    one row per reported track and step
    track_xy : (R, 2) float    its position (m)
    last_step : int    the run's last step S

    Returns
    -------
    ``(confirmations, deletions)``: a confirmation at a label's first report at step >= 1,
    a deletion at the step after its last report when that is before ``last_step``.
    """
    s = np.asarray(track_step, dtype=np.int64).reshape(-1)
    lab = np.asarray(track_label, dtype=np.int64).reshape(-1)
    xy = np.asarray(track_xy, dtype=float).reshape(-1, 2)[:, :2]
    order = np.lexsort((s, lab))                            # by label, then step
    s, lab, xy = s[order], lab[order], xy[order]
    first = np.flatnonzero(np.append(True, lab[1:] != lab[:-1])) if len(s) else s
    last = np.append(first[1:] - 1, len(s) - 1) if len(s) else s
    new = first[s[first] >= 1]
    gone = last[s[last] < last_step]
    return (_event_list(s[new], lab[new], xy[new]), _event_list(s[gone] + 1, lab[gone], xy[gone]))


def episode_events(episode: Episode) -> Events:
    """The births, deaths, confirmations and deletions of a run."""
    births, deaths = target_events(episode.alive, np.asarray(episode.truth)[..., :2])
    S = np.asarray(episode.alive).shape[0] - 1
    confirmed, deleted = track_events(episode.track_step, episode.track_label,
                                      np.asarray(episode.track_mean)[:, :2], S)
    return Events(births, deaths, confirmed, deleted)


def is_set_run(episode: Episode) -> bool:
    """Whether a run is one of changing sets: a multi-target tracker, or targets born or
    dying. A run of the tracker of known targets on a fixed set of targets is not (its
    figures stay those of known targets)."""
    return (episode.settings.tracker.kind != "known"
            or not bool(np.asarray(episode.alive).all()))


def slot_kinds(kinds: tuple[str, ...], n_slots: int) -> list[str]:
    """The kind of each of ``n_slots`` target slots: slot ``s`` moves as template
    ``s mod T`` of the scenario's ``T`` target kinds (``"scripted"`` for a scripted truth,
    which has no templates)."""
    if not kinds:
        return ["scripted"] * n_slots
    return [kinds[s % len(kinds)] for s in range(n_slots)]


def track_targets(episode: Episode, c: float | None = None) -> IntArray:
    """The target slot GOSPA assigns to each reported track row (-1: a false track), at
    every step including 0, with the cut-off ``c`` (m; None: the run's ``gospa_c``).

    Returns
    -------
    (R,) int64, aligned with ``episode.track_step``.
    """
    c = episode.settings.gospa_c if c is None else c
    alive = np.asarray(episode.alive)
    steps, ids = np.nonzero(alive)
    truth = np.asarray(episode.truth)
    sm = set_metrics(steps, ids, truth[steps, ids, :2], episode.track_step,
                     episode.track_label, np.asarray(episode.track_mean)[:, :2], c,
                     n_steps=alive.shape[0])
    out = np.full(len(episode.track_step), -1, dtype=np.int64)
    # (step, label) -> row, for the rows of assigned targets
    width = int(np.max(episode.track_label, initial=0)) + 1
    key = np.asarray(episode.track_step, dtype=np.int64) * width + episode.track_label
    order = np.argsort(key, kind="stable")
    ok = sm.assigned
    want = steps[ok] * width + sm.label[ok]
    out[order[np.searchsorted(key[order], want)]] = ids[ok]
    return out


def looked_labels(episode: Episode) -> IntArray:
    """The label of the track each sensor looked at, ``(S+1, N)`` (-1: no look).

    A run records the look as an index into the track set the epoch started from (the set
    reported at the step before the epoch's first step); with the tracker of known targets
    that index is the target. Looks whose index is outside that set are -1.
    """
    looked = np.asarray(episode.looked, dtype=np.int64)
    if episode.settings.tracker.kind == "known":
        return looked
    S1 = looked.shape[0]
    e = int(episode.settings.steps_per_epoch)
    t = np.arange(S1)
    snapshot = np.maximum(t - 1 - (np.maximum(t, 1) - 1) % e, 0)    # epoch start - 1
    steps = np.asarray(episode.track_step, dtype=np.int64)
    start = np.searchsorted(steps, snapshot)
    count = np.searchsorted(steps, snapshot, side="right") - start
    ok = (looked >= 0) & (looked < count[:, None])
    row = np.where(ok, start[:, None] + np.maximum(looked, 0), 0)
    labels = np.asarray(episode.track_label, dtype=np.int64)
    return np.where(ok, labels[row] if len(labels) else -1, -1)


def study_has_sets(study: Study) -> bool:
    """Whether a study is one of changing sets: a method with a multi-target tracker, or a
    truth whose targets are born, die or are scripted."""
    sc = study.scenario
    return (any(m.settings.tracker.kind != "known" for m in study.methods)
            or sc.births != "none" or sc.survival_probability < 1.0
            or sc.scripted is not None)
