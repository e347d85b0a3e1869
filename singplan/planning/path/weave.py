"""Weave: a lateral oscillation superposed on a LIN or CIRC, as in arc welding (SEEDS 002).

DESIGN.md ("Task YAML", ``weave``): at arc length ``s`` along the base path the TCP is offset by

    a * f(2 pi s / lambda) * n(s),   n = (z_tcp x t) / |z_tcp x t|

with ``a`` the amplitude, ``f`` = sin (``sine``) or the unit triangle wave (``triangle``, in phase
with the sine: 0 at s = 0, rising), ``z_tcp`` the base path's tool z axis and ``t`` the base path's
tangent, so the weave turns with the path and the tool. The orientation is the base path's. The
wavelength is adjusted to a whole number of periods ``P = max(1, round(L / lambda))`` along the
move, so the weave starts and ends on the path.

A :class:`WovenPiece` is a :class:`~singplan.planning.path.cartesian.CartesianPiece` whose poses carry the offset;
its parameter ``u`` and ``length_m`` stay those of the base path, so the timing's arc-length
coordinate ``u * L`` (capped at the programmed speed) is the speed along the base path, as
DESIGN.md asks; the TCP itself moves faster by the lateral motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from singplan.errors import TaskError
from singplan.planning.path.cartesian import CartesianPiece
from singplan.task.schema import Weave

# Path samples per weave period, uniform: a multiple of 4, so that with a whole number of periods
# the triangle's corners (quarter periods) fall on samples.
SAMPLES_PER_PERIOD = 32
# At a triangle's corners the joint velocities jump; the output samples keep the acceleration
# limit only if the timing slows there as much as the samples need. The joints' reference spline
# handed to TOPP-RA rounds a corner over about one path sample, so corners get extra samples this
# close (in quarter periods) on either side: the spline turns about as sharply as the samples do.
# Without them a 3 mm / 6 mm triangle at 20 mm/s failed the acceleration limit (x1.01), and a
# 3 mm / 20 mm one at 50 mm/s through a wrist singularity x7 (tests/test_weave.py).
CORNER_OFFSETS = 10.0 ** -np.arange(1.0, 5.0)
# Below this angle between the tool's z axis and the path the lateral direction z x t turns too
# fast to weave along (and at 0 it does not exist): bad input.
MIN_LATERAL_DEG = 1.0
_CHECK_STEP_RAD = math.radians(0.5)  # grid of that check: the tangent and the tool turn at most this much
_DRAW_POINTS_PER_PERIOD = 16
_DRAW_POINTS_MAX = 20_000  # a replay draws at most this many points of one woven move


def wave(pattern: str, x: np.ndarray) -> np.ndarray:
    """The unit waveform at phase x [rad]: sin, or the triangle wave through (0, 0), (pi/2, 1), (3 pi/2, -1)."""
    if pattern == "sine":
        return np.sin(x)
    p = np.mod(x / (2.0 * math.pi) + 0.25, 1.0)  # folded, not asin(sin x): exact at the corners
    return 1.0 - 4.0 * np.abs(p - 0.5)


def wave_slope(pattern: str, x: np.ndarray) -> np.ndarray:
    """d wave / dx; the triangle's one-sided slope (the rising side at its corners' left)."""
    if pattern == "sine":
        return np.cos(x)
    p = np.mod(x / (2.0 * math.pi) + 0.25, 1.0)
    return np.where(p < 0.5, 2.0 / math.pi, -2.0 / math.pi)


def whole_periods(length_m: float, wavelength_m: float) -> int:
    """Periods along a move of ``length_m``: the nearest whole number, at least one."""
    return max(1, round(length_m / wavelength_m))


@dataclass(frozen=True)
class WovenPiece(CartesianPiece):
    """A LIN / CIRC with its weave; ``u`` and ``length_m`` are the base path's."""

    weave: Weave | None = None
    periods: int = 1

    @property
    def amplitude_m(self) -> float:
        assert self.weave is not None
        return self.weave.amplitude_mm / 1e3

    @property
    def steepest_slope(self) -> float:
        """The weave's steepest slope against its base path: a (2 pi P / L) max|f'| (amplitude a, P
        periods over the base length L, f' = cos for a sine, 2 / pi for the triangle)."""
        assert self.weave is not None
        steepest = 1.0 if self.weave.pattern == "sine" else 2.0 / math.pi
        return self.amplitude_m * 2.0 * math.pi * self.periods / self.length_m * steepest

    def base_poses(self, u: np.ndarray) -> np.ndarray:
        """Homogeneous poses (N, 4, 4) of the base path, without the weave."""
        return super().poses(u)

    def poses(self, u: np.ndarray) -> np.ndarray:
        T = self.base_poses(u)
        T[:, :3, 3] += self.offsets(np.asarray(u, dtype=float), T)
        return T

    def offsets(self, u: np.ndarray, T_base: np.ndarray) -> np.ndarray:
        """Weave offsets (N, 3) [m] at parameters u (N,), given the base poses there."""
        assert self.weave is not None
        n, _ = self._lateral(T_base)
        f = wave(self.weave.pattern, 2.0 * math.pi * self.periods * u)
        return (self.amplitude_m * f)[:, None] * n

    def _tangents(self, T_base: np.ndarray) -> np.ndarray:
        """dp/du (N, 3) of the base path."""
        if self.kind == "lin":
            d = self.T_end.translation - self.T_start.translation
            return np.broadcast_to(d, (len(T_base), 3))
        assert self.center is not None and self.normal is not None
        return np.cross(self.arc_rad * self.normal, T_base[:, :3, 3] - self.center)

    def _lateral(self, T_base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit lateral directions n (N, 3) and the unnormalised z x dp/du (N, 3)."""
        w = np.cross(T_base[:, :3, 2], self._tangents(T_base))
        return w / np.linalg.norm(w, axis=1)[:, None], w

    def velocity(self, u: float) -> np.ndarray:
        """dX/du (6,) with the weave's lateral motion: the base path's plus d offset / du.

        The slerp turns the tool at ``omega`` (base frame, per unit u), so z' = omega x z; a CIRC's
        tangent turns with the arc, t' = k x t (k = arc_rad * normal); n' is the part of
        (z x t)' normal to n, over |z x t|.
        """
        assert self.weave is not None
        T = self.base_poses(np.array([u]))  # not super().velocity: that reads the (woven) poses
        n, w = self._lateral(T)
        n, w = n[0], w[0]
        z, t = T[0, :3, 2], self._tangents(T)[0]
        omega = self.T_start.rotation @ self.rotation_vector
        t_u = np.cross(self.arc_rad * self.normal, t) if self.kind == "circ" and self.normal is not None else 0.0 * t
        w_u = np.cross(np.cross(omega, z), t) + np.cross(z, t_u)
        n_u = (w_u - n * float(n @ w_u)) / float(np.linalg.norm(w))
        x = np.array([2.0 * math.pi * self.periods * u])
        f, f_x = float(wave(self.weave.pattern, x)[0]), float(wave_slope(self.weave.pattern, x)[0])
        lateral = self.amplitude_m * (f_x * 2.0 * math.pi * self.periods * n + f * n_u)
        return np.concatenate([t + lateral, omega])

    def _uniform_count(self, step_m: float, step_rad: float) -> int:
        """The base path's count, raised to :data:`SAMPLES_PER_PERIOD` a period, in whole quarter periods."""
        quarters = 4 * self.periods
        wanted = max(super().sample_count(step_m, step_rad), SAMPLES_PER_PERIOD * self.periods)
        return quarters * math.ceil(wanted / quarters)

    def _corner_samples(self) -> np.ndarray:
        """The extra path parameters around a triangle's corners (none for a sine)."""
        assert self.weave is not None
        if self.weave.pattern != "triangle":
            return np.empty(0)
        quarter = 1.0 / (4 * self.periods)
        corners = (2 * np.arange(2 * self.periods) + 1) * quarter
        return (corners[:, None] + np.concatenate([-CORNER_OFFSETS, CORNER_OFFSETS]) * quarter).ravel()

    def sample_count(self, step_m: float, step_rad: float) -> int:
        """Intervals of :meth:`grid` (what the work budget counts), without forming it."""
        corners = 2 * len(CORNER_OFFSETS) * 2 * self.periods if self.weave and self.weave.pattern == "triangle" else 0
        return self._uniform_count(step_m, step_rad) + corners

    def grid(self, step_m: float, step_rad: float) -> np.ndarray:
        """The planner's initial path parameters: uniform, plus the triangle's corner samples."""
        return np.union1d(np.linspace(0.0, 1.0, self._uniform_count(step_m, step_rad) + 1), self._corner_samples())

    def drawing_count(self) -> int:
        """Points a replay draws: enough to show the weave's periods."""
        return min(_DRAW_POINTS_MAX, max(super().drawing_count(), _DRAW_POINTS_PER_PERIOD * self.periods + 1))


def woven(piece: CartesianPiece, weave: Weave, field: str) -> WovenPiece:
    """The piece with its weave; ``field`` names the move (``moves[i].lin``) for bad input.

    A move with no length, or whose tool z axis comes within :data:`MIN_LATERAL_DEG` of the
    path's tangent anywhere, has no lateral direction to weave along: bad input.
    """
    where = f"{field}.weave"
    if piece.length_m < 1e-9:
        raise TaskError(where, "the move has no path length to weave along (its position does not change)")
    periods = whole_periods(piece.length_m, weave.wavelength_mm / 1e3)
    out = WovenPiece(**{f.name: getattr(piece, f.name) for f in fields(piece)}, weave=weave, periods=periods)
    _check_lateral(out, where)
    return out


def _check_lateral(piece: WovenPiece, where: str) -> None:
    """Refuse a weave whose lateral direction z_tcp x t vanishes (or nearly) along the move.

    Checked on a grid on which neither the tool nor the tangent turns more than 0.5 deg (at most
    ~1100 points whatever the move), so an exact alignment between grid points still shows as
    an angle under 1 deg.
    """
    count = 2 + math.ceil(max(piece.rotation_rad, piece.arc_rad) / _CHECK_STEP_RAD)
    u = np.linspace(0.0, 1.0, max(65, count))
    T = piece.base_poses(u)
    t = piece._tangents(T)
    w = np.cross(T[:, :3, 2], t)
    sin_angle = np.linalg.norm(w, axis=1) / np.linalg.norm(t, axis=1)
    k = int(np.argmin(sin_angle))
    angle_deg = math.degrees(math.asin(min(1.0, float(sin_angle[k]))))
    if angle_deg < MIN_LATERAL_DEG:
        p = T[k, :3, 3]
        at = f"s = {u[k] * piece.length_m * 1e3:.1f} mm (xyz {p[0]:.4f} {p[1]:.4f} {p[2]:.4f} m)"
        raise TaskError(where, f"the tool's z axis runs along the path ({angle_deg:.2f} deg from it at "
                               f"{at}): a weave needs the lateral "
                               f"direction z_tcp x tangent, so the tool must stand at least {MIN_LATERAL_DEG:g} deg "
                               "off the path")
