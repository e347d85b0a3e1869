"""How singplan compiles its per-sample loops (numba).

The planner works on a few hundred samples at a time, many times per move. Written as
vectorised numpy, such a step pays the fixed cost of every array operation it is made of
(1-5 us each) and ends up costing milliseconds whatever the number of samples; a compiled
scalar loop costs about what its arithmetic costs. Functions are cached on disk
(``cache=True``), so only the first run after an install pays the compilation (seconds).
"""

from __future__ import annotations

import numba

jit = numba.njit(cache=True, nogil=True)
