"""How singplan compiles its per-sample loops (numba).

The planner works on a few hundred samples at a time, many times per move. Written as
vectorised numpy, such a step pays the fixed cost of every array operation it is made of
(1-5 us each) and ends up costing milliseconds whatever the number of samples; a compiled
scalar loop costs about what its arithmetic costs.

Kernels are cached on disk (``cache=True``: next to the modules, or in numba's user cache
when that folder is read-only; ``NUMBA_CACHE_DIR`` moves it), so only the first run after
an install pays the compilation, about 10 s on two cores. numba checks a cached kernel
against its own source file only, so a kernel calls kernels of its own module and, for angle
wraps and whole-turn shifts, those of :mod:`singplan.kinematics.angles` (the one home of those
formulas): a change there must come with a cleared cache (delete the ``*.nbi`` / ``*.nbc``
files, or point ``NUMBA_CACHE_DIR`` at a fresh folder).
"""

from __future__ import annotations

import numba

jit = numba.njit(cache=True, nogil=True)

