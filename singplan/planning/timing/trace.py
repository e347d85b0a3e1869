"""The TCP's own travel along a joint map that leaves its path (:class:`~singplan.planning.timing.records.TcpTrace`),
so that the programmed speed caps the TCP and not only the path parameter."""

from __future__ import annotations

import math

import numpy as np

from singplan.planning.path.jointmap import JointMap
from singplan.planning.timing.records import TcpTrace

_TRACE_STEP_M = 2.5e-4  # the trace's samples inside a part that leaves the path: every 0.25 mm of path ...
_TRACE_STEP_RAD = math.radians(0.25)  # ... and 0.25 deg of any joint
_TRACE_MIN, _TRACE_MAX = 64, 20_000  # samples a part, at least and at most


def tcp_trace(jmap: JointMap, length_m: float) -> TcpTrace | None:
    """The TCP's own travel along a LIN / CIRC joint map (:class:`TcpTrace`), where it has parts
    that leave the path and its TCP runs ahead of the path somewhere; None where the path's arc
    length bounds the TCP's (every part keeps the position, or the parts off it run no faster)."""
    off = jmap.off_path_parts
    if not off or length_m <= 0.0:
        return None
    u_ref, _ = jmap.reference()
    dense = [u_ref]
    for part in off:
        travel = float(np.max(np.sum(np.abs(np.diff(part.q, axis=0)), axis=0), initial=0.0))
        count = max(_TRACE_MIN, math.ceil((part.u1 - part.u0) * length_m / _TRACE_STEP_M),
                    math.ceil(travel / _TRACE_STEP_RAD))
        dense.append(np.linspace(part.u0, part.u1, min(count, _TRACE_MAX) + 1))
    u = np.unique(np.concatenate(dense))
    path_m = np.diff(u) * length_m
    tcp_m = np.linalg.norm(np.diff(jmap.robot.tcp_positions(jmap.evaluate(u)), axis=0), axis=1)
    if np.all(tcp_m <= path_m * (1.0 + 1e-9) + 1e-12):
        return None  # the TCP never runs ahead of the path (an axis part that keeps to it): as without a trace
    return TcpTrace(jmap.robot, u, np.concatenate([[0.0], np.cumsum(np.maximum(path_m, tcp_m))]))
