"""One colour scheme for every figure (episode map, timeline, animation, study report).

Each palette has one meaning, and no two meanings share a colour:

- **targets**: a qualitative palette (Tableau 10 without its grey); target ``j`` has the
  same colour in every figure of a run and in a study's scenario figure;
- **sensors**: black and greys, told apart by their markers, so that a sensor is never
  mistaken for a target;
- **methods** (study report): Dark2 without its grey, then darker shades of its hues;
- **target kinds** (study report): slate, crimson and charcoal, used nowhere else;
- **false tracks** (a multi-target tracker's tracks assigned to no target): black, dashed;
- **mean / median** markers (study report): black filled circle and grey open diamond;
- **the undetected intensity** (expected targets not yet detected, per km^2): the sequential
  map :data:`INTENSITY_CMAP`, light where there are few, drawn under everything else.

Plain hex strings: this module imports no plotting library.
"""

from __future__ import annotations

from collections.abc import Sequence

#: Tableau 10 without its grey (#7f7f7f, kept for sensors): one colour per target index.
TARGET_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                  "#e377c2", "#bcbd22", "#17becf")
#: Sensors: black and greys, each with its own marker.
SENSOR_GREYS = ("#000000", "#555555", "#8a8a8a", "#2b2b2b", "#707070", "#a0a0a0")
SENSOR_MARKERS = ("^", "s", "D", "v", "p", "h", "<", ">", "8", "*")
#: Study methods: Dark2 without its grey, then (more than 7 methods) further dark shades.
METHOD_PALETTE = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02",
                  "#a6761d", "#01665e", "#542788", "#b35806", "#4d9221", "#8e0152",
                  "#7f6b00")
#: Target kinds in the study report (colours no other palette uses).
KIND_COLORS = {"cv": "#3a5a98", "dubins": "#b2182b", "all": "#404040"}
KIND_MARKERS = {"cv": "o", "dubins": "s", "all": "D"}
#: Fallback for a target kind not listed above.
OTHER_KIND = "#6b4f2a"
#: Summary statistics (mean: filled, median: open).
MEAN_COLOR = "#111111"
MEDIAN_COLOR = "#7a7a7a"
#: A reported track that GOSPA assigns to no target (drawn dashed, so that it is not taken
#: for a sensor's grey).
FALSE_TRACK = "#000000"
#: Colour map (a matplotlib name) of the undetected intensity: white-yellow to dark blue,
#: light at zero so that the scene drawn over it stays readable.
INTENSITY_CMAP = "YlGnBu"
#: Buildings: light fill, darker outline.
BUILDING_FACE = "#d9d9d9"
BUILDING_EDGE = "#6e6e6e"


def target_color(j: int) -> str:
    """Colour of target ``j`` (cycles after :data:`TARGET_PALETTE`)."""
    return TARGET_PALETTE[int(j) % len(TARGET_PALETTE)]


def target_colors(m: int) -> list[str]:
    """Colours of targets ``0..m-1``."""
    return [target_color(j) for j in range(m)]


def sensor_style(i: int) -> tuple[str, str]:
    """``(colour, marker)`` of sensor ``i``: a grey and a marker; the pair is unique for the
    first 30 sensors."""
    i = int(i)
    return SENSOR_GREYS[i % len(SENSOR_GREYS)], SENSOR_MARKERS[i % len(SENSOR_MARKERS)]


def method_colors(names: Sequence[str]) -> dict[str, str]:
    """Colour of each study method, in the given order (cycles after 13 methods)."""
    return {n: METHOD_PALETTE[k % len(METHOD_PALETTE)] for k, n in enumerate(names)}


def kind_color(kind: str) -> str:
    """Colour of a target kind (``cv``, ``dubins`` or ``all``)."""
    return KIND_COLORS.get(kind, OTHER_KIND)


def kind_marker(kind: str) -> str:
    """Marker of a target kind in the report's interval plots."""
    return KIND_MARKERS.get(kind, "P")


def mix(color: str, weight: float, background: str = "#ffffff") -> tuple[float, float, float]:
    """``weight * color + (1 - weight) * background`` as an RGB triple in [0, 1]: a
    lighter tint of ``color`` for small weights (no transparency, so overlaps stay clean)."""
    w = min(max(float(weight), 0.0), 1.0)
    c, b = _rgb(color), _rgb(background)
    return (w * c[0] + (1 - w) * b[0], w * c[1] + (1 - w) * b[1], w * c[2] + (1 - w) * b[2])


def mix_hex(color: str, weight: float, background: str = "#ffffff") -> str:
    """:func:`mix` as a hex string."""
    return "#" + "".join(f"{round(255 * v):02x}" for v in mix(color, weight, background))


def _rgb(color: str) -> tuple[float, float, float]:
    h = color.lstrip("#")
    return (int(h[0:2], 16) / 255.0, int(h[2:4], 16) / 255.0, int(h[4:6], 16) / 255.0)
