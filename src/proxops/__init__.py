"""proxops: spacecraft rendezvous and proximity operations toolkit.

Internal conventions (see DESIGN.md / docs in each module):
SI units, Hill/RTN relative frame (x radial out, y along-track, z orbit normal),
scalar-last Hamilton quaternions, dynamics signature f(t, x, u, params).
"""

__version__ = "0.1.0"
