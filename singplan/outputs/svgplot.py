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

PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf")
LIMIT_COLOUR = "#d62728"
_PX_PER_INCH = 96  # panel heights are given in inches, as the report's layout was
_WIDTH_PX = 960
_MARGIN = {"left": 58, "right": 14, "top": 24, "bottom": 34, "top_axis": 30}
_FONT = "font-family:system-ui,sans-serif"


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


def _panel_svg(p: Panel, x0: float, y0: float, w: float, h: float, clip: str) -> list[str]:
    """SVG elements of a panel in the box (x0, y0, w, h) [px]; ``clip`` names its clip path (unique in the page)."""
    top_pad = _MARGIN["top"] + (_MARGIN["top_axis"] if p.top else 0)
    left, right, top, bottom = x0 + _MARGIN["left"], x0 + w - _MARGIN["right"], y0 + top_pad, y0 + h - _MARGIN["bottom"]
    xlo, xhi = _limits([c.x for c in p.curves])
    ylo, yhi = _limits([c.y for c in p.curves] + [np.array([y for y, *_ in p.hlines])])

    def px(x: np.ndarray) -> np.ndarray:
        return left + (np.asarray(x, dtype=float) - xlo) / (xhi - xlo) * (right - left)

    def py(y: np.ndarray) -> np.ndarray:
        return bottom - (np.asarray(y, dtype=float) - ylo) / (yhi - ylo) * (bottom - top)

    out = [f'<clipPath id="{clip}"><rect x="{left:.1f}" y="{top:.1f}" width="{right - left:.1f}" '
           f'height="{bottom - top:.1f}"/></clipPath>', f'<g clip-path="url(#{clip})">']
    for a, b, colour, opacity in p.spans:
        xa, xb = px(np.array([max(a, xlo), min(b, xhi)]))
        if xb > xa:
            out.append(f'<path d="M{xa:.1f} {top:.1f}H{xb:.1f}V{bottom:.1f}H{xa:.1f}Z" fill="{colour}" '
                       f'fill-opacity="{opacity}"/>')
    for y, colour, dashed, a, b in p.hlines:
        xa, xb = px(np.array([xlo if a is None else a, xhi if b is None else b]))
        dash = ' stroke-dasharray="5 3"' if dashed else ""
        out.append(f'<path d="M{xa:.1f} {float(py(y)):.1f}H{xb:.1f}" stroke="{colour}" stroke-width="0.9"{dash}/>')
    for c in p.curves:
        out.append(f'<path d="{_polyline(px(c.x), py(c.y))}" fill="none" stroke="{c.colour}" '
                   f'stroke-width="{c.width}" stroke-linejoin="round"/>')
    for x, y, text, colour in p.points:
        cx, cy = float(px(x)), float(py(y))
        out.append(f'<path d="M{cx - 3:.1f} {cy:.1f}a3 3 0 1 0 6 0a3 3 0 1 0 -6 0Z" fill="{colour}"/>')
        anchor = "end" if cx > right - 80 else "start"
        out.append(_text(cx + (-6 if anchor == "end" else 6), cy + 12, text, 10, anchor))
    out.append("</g>")
    out.append(f'<path d="M{left:.1f} {top:.1f}H{right:.1f}V{bottom:.1f}H{left:.1f}Z" fill="none" stroke="#333" '
               'stroke-width="0.8"/>')
    out += _x_ticks(nice_ticks(xlo, xhi), px, bottom, 1)
    out += _y_ticks(nice_ticks(ylo, yhi, 5), py, left)
    if p.top:
        label, to_top, from_top = p.top
        ends = to_top(np.array([xlo, xhi]))
        ticks = nice_ticks(float(ends[0]), float(ends[1]))
        out += _x_ticks(ticks, lambda v: px(from_top(v)), top, -1)
        out.append(_text(0.5 * (left + right), top - 20, label, 10))
    out.append(_text(0.5 * (left + right), y0 + top_pad - (34 if p.top else 8), p.title, 11))
    out.append(_text(0.5 * (left + right), bottom + 30, p.xlabel, 10))
    if p.ylabel:
        cy = 0.5 * (top + bottom)
        out.append(f'<text x="{x0 + 12:.1f}" y="{cy:.1f}" transform="rotate(-90 {x0 + 12:.1f} {cy:.1f})" '
                   f'text-anchor="middle" font-size="10" style="{_FONT}">{escape(p.ylabel)}</text>')
    if p.legend:
        out += _legend(p, left + 6, top + 6)
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


def _x_ticks(ticks: np.ndarray, px: Callable[[np.ndarray], np.ndarray], y: float, side: int) -> list[str]:
    """Ticks on a horizontal axis at height y: pointing down (side 1, labels below) or up (-1, above)."""
    out = []
    for value, x in zip(ticks.tolist(), np.atleast_1d(px(ticks)).tolist(), strict=True):
        if not math.isfinite(x):
            continue
        out.append(f'<path d="M{x:.1f} {y:.1f}v{4 * side}" stroke="#333" stroke-width="0.8"/>')
        out.append(_text(x, y + (14 if side > 0 else -7), _label(value), 9))
    return out


def _y_ticks(ticks: np.ndarray, py: Callable[[np.ndarray], np.ndarray], x: float) -> list[str]:
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
