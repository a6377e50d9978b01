"""Orbit data in and out: two-line element sets (:mod:`.tle`, through the ``sgp4`` package) and
CCSDS Navigation Data Messages in KVN (:mod:`.ccsds`: OPM read, OEM write and read).

States are in the truth's inertial frame (:mod:`proxops.environment.earth`: J2000 mean equator
and equinox axes, IAU-76/80 truncated), SI units inside; the files carry km and km/s.
"""
