"""proxops: spacecraft rendezvous and proximity operations toolkit.

Internal conventions (see DESIGN.md / docs in each module):
SI units, Hill/RTN relative frame (x radial out, y along-track, z orbit normal),
scalar-last Hamilton quaternions, dynamics signature f(t, x, u, params).
"""

__version__ = "0.1.0"

from proxops._numba_cache import stamp_numba_cache as _stamp_numba_cache

_stamp_numba_cache()  # numba's disk cache keyed by all proxops sources, set when numba is imported (proxops._numba_cache)
