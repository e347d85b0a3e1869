"""How singplan compiles its per-sample loops (numba).

The planner works on a few hundred samples at a time, many times per move. Written as
vectorised numpy, such a step pays the fixed cost of every array operation it is made of
(1-5 us each) and ends up costing milliseconds whatever the number of samples; a compiled
scalar loop costs about what its arithmetic costs.

Kernels are cached on disk (``cache=True``: next to the modules, or in numba's user cache
when that folder is read-only; ``NUMBA_CACHE_DIR`` moves it), so only the first run after
an install pays the compilation, about 6 s of CPU time (docs/kinematics.md has the measurements).

A kernel calls kernels of its own module and those of :mod:`singplan.kinematics.angles` (the
one home of angle wraps and whole-turn shifts). numba checks a cached kernel against its own
source file only: a kernel compiled with an older ``angles.py`` would keep running the old
formulas. So every kernel's cache name carries a digest of ``angles.py`` (:data:`SHARED_DIGEST`),
and a change there compiles the kernels again instead.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba

_njit = numba.njit(cache=True, nogil=True)
_njit_fused = numba.njit(cache=True, nogil=True, fastmath={"contract"})


def _digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    except OSError:  # no source beside the package (a frozen application): nothing can change
        return "frozen"


SHARED_DIGEST = _digest(Path(__file__).with_name("angles.py"))


def _named(func: Callable[..., Any]) -> Callable[..., Any]:
    func.__qualname__ = f"{func.__qualname__}__{SHARED_DIGEST}"  # numba names the cache files after it
    return func


def jit(func: Callable[..., Any]) -> Any:
    """numba.njit(cache=True, nogil=True), cached under the function's name and :data:`SHARED_DIGEST`."""
    return _njit(_named(func))


def jit_fused(func: Callable[..., Any]) -> Any:
    """:func:`jit` with ``a * b + c`` fused into one rounding where the CPU has FMA (fastmath "contract"
    only: no reordering, no approximations), for the kernels that form products as BLAS does
    (:mod:`singplan.kinematics.chain`)."""
    return _njit_fused(_named(func))
