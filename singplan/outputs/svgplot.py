"""Small static line plots written straight as SVG text, for the report.

The report draws a dozen panels of curves with limits, shaded stretches and a marked worst
point; matplotlib did that in about a second (and as long again to import) for a two-move
plan. Here a panel is a few SVG paths: curves, dashed limit lines, shaded spans, axes with
1-2-5 ticks, a title, axis labels, an optional legend and an optional second x axis on top
(e.g. path length over time). Curves are drawn as given: decimating them is the caller's job
(:func:`envelope` keeps every bucket's minimum and maximum, so no peak is lost).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from html import escape

import numpy as np
from numpy.typing import ArrayLike

PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf")
LIMIT_COLOUR = "#d62728"
_PX_PER_INCH = 96  # panel heights are given in inches, as the report's layout was
_WIDTH_PX = 960
_MARGIN = {"left": 58, "right": 14, "top": 24, "bottom": 34, "top_axis": 30}
_FONT = "font-family:system-ui,sans-serif"
_MIN_LABEL_GAP_PX = 36  # tick labels of a horizontal axis at least this far apart


@dataclass
class _Curve:
    x: np.ndarray
    y: np.ndarray
    colour: str
    width: float
    label: str


@dataclass
class Panel:
    """One plot: add curves, limit lines, spans and points, then :func:`figure_svg` lays panels out."""

    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    legend: bool = False
    # a second x axis on top: its label and the map from x to its values (increasing) and back
    top: tuple[str, Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]] | None = None
    curves: list[_Curve] = field(default_factory=list)
    hlines: list[tuple[float, str, bool, float | None, float | None]] = field(default_factory=list)
    spans: list[tuple[float, float, str, float]] = field(default_factory=list)
    points: list[tuple[float, float, str, str]] = field(default_factory=list)

    def curve(self, x: np.ndarray, y: np.ndarray, label: str = "", colour: str | None = None,
              width: float = 1.2) -> None:
        self.curves.append(_Curve(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                  colour or PALETTE[len(self.curves) % len(PALETTE)], width, label))

    def hline(self, y: float, colour: str = LIMIT_COLOUR, dashed: bool = True,
              x0: float | None = None, x1: float | None = None) -> None:
        """A horizontal line at ``y`` (dashed: a limit), across the panel or from x0 to x1."""
        self.hlines.append((float(y), colour, dashed, x0, x1))

    def span(self, x0: float, x1: float, colour: str, opacity: float) -> None:
        self.spans.append((float(x0), float(x1), colour, opacity))

    def point(self, x: float, y: float, text: str, colour: str = LIMIT_COLOUR) -> None:
        """A marked point with a text beside it (the worst figure of a curve)."""
        self.points.append((float(x), float(y), text, colour))


def envelope(x: np.ndarray, y: np.ndarray, buckets: int) -> tuple[np.ndarray, np.ndarray]:
    """The curve to draw: y itself, or for long series the minimum and maximum of each of
    ``buckets`` buckets (a page of a million samples stays small and no spike is lost)."""
    if len(y) <= 2 * buckets:
        return x, y
    starts = np.linspace(0, len(y), buckets + 1).astype(np.int64)[:-1]
    low, high = np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)
    return np.repeat(x[starts], 2), np.column_stack([low, high]).ravel()


def nice_ticks(lo: float, hi: float, count: int = 6) -> np.ndarray:
    """Round tick values (1, 2, 2.5 or 5 times a power of ten apart) covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return np.array([lo]) if math.isfinite(lo) else np.empty(0)
    raw = (hi - lo) / max(1, count - 1)
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * power >= raw)
    first = math.ceil(lo / step - 1e-9)
    ticks = (first + np.arange(math.floor(hi / step + 1e-9) - first + 1)) * step
    return np.where(np.abs(ticks) < 1e-12 * step, 0.0, ticks)


def _label(value: float) -> str:
    return f"{value:.6g}"


def _limits(values: list[np.ndarray]) -> tuple[float, float]:
    finite = [v[np.isfinite(v)] for v in values if len(v)]
    finite = [v for v in finite if len(v)]
    if not finite:
        return 0.0, 1.0
    lo, hi = min(float(v.min()) for v in finite), max(float(v.max()) for v in finite)
    if hi - lo < 1e-12 * max(1.0, abs(hi)):
        pad = max(1e-9, 0.05 * abs(hi))
        return lo - pad, hi + pad
    margin = 0.05 * (hi - lo)
    return lo - margin, hi + margin


@dataclass(frozen=True)
class _Frame:
    """A panel's plot area [px] and the data ranges it shows."""

    left: float
    right: float
    top: float
    bottom: float
    x: tuple[float, float]
    y: tuple[float, float]

    def px(self, x: ArrayLike) -> np.ndarray:
        scale = (self.right - self.left) / (self.x[1] - self.x[0])
        return self.left + (np.asarray(x, dtype=float) - self.x[0]) * scale

    def py(self, y: ArrayLike) -> np.ndarray:
        scale = (self.bottom - self.top) / (self.y[1] - self.y[0])
        return self.bottom - (np.asarray(y, dtype=float) - self.y[0]) * scale


def _panel_svg(p: Panel, x0: float, y0: float, w: float, h: float, clip: str) -> list[str]:
    """SVG elements of a panel in the box (x0, y0, w, h) [px]; ``clip`` names its clip path (unique in the page)."""
    top_pad = _MARGIN["top"] + (_MARGIN["top_axis"] if p.top else 0)
    f = _Frame(x0 + _MARGIN["left"], x0 + w - _MARGIN["right"], y0 + top_pad, y0 + h - _MARGIN["bottom"],
               _limits([c.x for c in p.curves]),
               _limits([c.y for c in p.curves] + [np.array([line[0] for line in p.hlines])]))
    out = [f'<clipPath id="{clip}"><rect x="{f.left:.1f}" y="{f.top:.1f}" width="{f.right - f.left:.1f}" '
           f'height="{f.bottom - f.top:.1f}"/></clipPath>', f'<g clip-path="url(#{clip})">', *_data(p, f), "</g>"]
    out.append(f'<path d="M{f.left:.1f} {f.top:.1f}H{f.right:.1f}V{f.bottom:.1f}H{f.left:.1f}Z" fill="none" '
               'stroke="#333" stroke-width="0.8"/>')
    out += _x_ticks(nice_ticks(*f.x), f.px, f.bottom, 1)
    out += _y_ticks(nice_ticks(*f.y, 5), f.py, f.left)
    centre = 0.5 * (f.left + f.right)
    if p.top:
        label, to_top, from_top = p.top
        ends = to_top(np.array(f.x))
        out += _x_ticks(nice_ticks(float(ends[0]), float(ends[1])), lambda v: f.px(from_top(np.asarray(v))), f.top, -1)
        out.append(_text(centre, f.top - 20, label, 10))
    out.append(_text(centre, y0 + top_pad - (34 if p.top else 8), p.title, 11))
    out.append(_text(centre, f.bottom + 30, p.xlabel, 10))
    if p.ylabel:
        cy = 0.5 * (f.top + f.bottom)
        out.append(f'<text x="{x0 + 12:.1f}" y="{cy:.1f}" transform="rotate(-90 {x0 + 12:.1f} {cy:.1f})" '
                   f'text-anchor="middle" font-size="10" style="{_FONT}">{escape(p.ylabel)}</text>')
    if p.legend:
        out += _legend(p, f.left + 6, f.top + 6)
    return out


def _data(p: Panel, f: _Frame) -> list[str]:
    """The panel's spans, limit lines, curves and marked points, in that order (later on top)."""
    out = []
    for a, b, colour, opacity in p.spans:
        xa, xb = f.px([max(a, f.x[0]), min(b, f.x[1])])
        if xb > xa:
            out.append(f'<path d="M{xa:.1f} {f.top:.1f}H{xb:.1f}V{f.bottom:.1f}H{xa:.1f}Z" fill="{colour}" '
                       f'fill-opacity="{opacity}"/>')
    for level, colour, dashed, start, end in p.hlines:
        xa, xb = f.px([f.x[0] if start is None else start, f.x[1] if end is None else end])
        dash = ' stroke-dasharray="5 3"' if dashed else ""
        out.append(f'<path d="M{xa:.1f} {float(f.py(level)):.1f}H{xb:.1f}" stroke="{colour}" '
                   f'stroke-width="0.9"{dash}/>')
    for c in p.curves:
        out.append(f'<path d="{_polyline(f.px(c.x), f.py(c.y))}" fill="none" stroke="{c.colour}" '
                   f'stroke-width="{c.width}" stroke-linejoin="round"/>')
    for x, y, text, colour in p.points:
        cx, cy = float(f.px(x)), float(f.py(y))
        out.append(f'<path d="M{cx - 3:.1f} {cy:.1f}a3 3 0 1 0 6 0a3 3 0 1 0 -6 0Z" fill="{colour}"/>')
        anchor = "end" if cx > f.right - 80 else "start"
        out.append(_text(cx + (-6 if anchor == "end" else 6), cy + 12, text, 10, anchor))
    return out


def _polyline(xs: np.ndarray, ys: np.ndarray) -> str:
    if len(xs) == 0:
        return "M0 0"
    pairs = np.round(np.column_stack([xs, ys]), 1)
    pairs = pairs[np.isfinite(pairs).all(axis=1)]
    if len(pairs) == 0:
        return "M0 0"
    flat = pairs.tolist()
    return f"M{flat[0][0]:g} {flat[0][1]:g}" + "".join(f"L{x:g} {y:g}" for x, y in flat[1:])


def _x_ticks(ticks: np.ndarray, px: Callable[[ArrayLike], np.ndarray], y: float, side: int) -> list[str]:
    """Ticks on a horizontal axis at height y: pointing down (side 1, labels below) or up (-1, above).
    A label that would overlap the previous one is left out (a path-length axis crowds where the
    TCP moves fast); its tick stays."""
    out, last = [], -math.inf
    for value, x in zip(ticks.tolist(), np.atleast_1d(px(ticks)).tolist(), strict=True):
        if not math.isfinite(x):
            continue
        out.append(f'<path d="M{x:.1f} {y:.1f}v{4 * side}" stroke="#333" stroke-width="0.8"/>')
        if x - last >= _MIN_LABEL_GAP_PX:
            out.append(_text(x, y + (14 if side > 0 else -7), _label(value), 9))
            last = x
    return out


def _y_ticks(ticks: np.ndarray, py: Callable[[ArrayLike], np.ndarray], x: float) -> list[str]:
    out = []
    for value, y in zip(ticks.tolist(), np.atleast_1d(py(ticks)).tolist(), strict=True):
        out.append(f'<path d="M{x:.1f} {y:.1f}h-4" stroke="#333" stroke-width="0.8"/>')
        out.append(_text(x - 6, y + 3, _label(value), 9, "end"))
    return out


def _legend(p: Panel, x: float, y: float) -> list[str]:
    out, cx = [], x
    for c in p.curves:
        if not c.label:
            continue
        out.append(f'<path d="M{cx:.1f} {y + 4:.1f}h14" stroke="{c.colour}" stroke-width="2"/>')
        out.append(_text(cx + 17, y + 7, c.label, 9, "start"))
        cx += 24 + 6 * len(c.label)
    return out


def _text(x: float, y: float, text: str, size: int, anchor: str = "middle") -> str:
    return (f'<text x="{x:.1f}" y="{y:.1f}" text-anchor="{anchor}" font-size="{size}" '
            f'style="{_FONT}">{escape(text)}</text>')


def figure_svg(key: str, panels: Sequence[Panel], columns: int = 1, height_in: float = 3.0) -> str:
    """An ``<svg>`` of the panels in a grid of ``columns``, ``height_in`` inches high in all; ``key``
    (unique in the page) prefixes its element ids."""
    rows = math.ceil(len(panels) / columns)
    height = round(height_in * _PX_PER_INCH)
    w, h = _WIDTH_PX / columns, height / rows
    body = [e for i, p in enumerate(panels)
            for e in _panel_svg(p, (i % columns) * w, (i // columns) * h, w, h, f"{key}-clip{i}")]
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{_WIDTH_PX}" height="{height}" '
            f'viewBox="0 0 {_WIDTH_PX} {height}">' + "".join(body) + "</svg>")
