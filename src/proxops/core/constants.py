"""Physical constants (SI). Source: EGM2008 / WGS-84 values as used by Vallado,
*Fundamentals of Astrodynamics and Applications*, 4th ed., Table D-1."""

MU_EARTH = 3.986004418e14  # m^3/s^2
R_EARTH = 6378137.0  # m, equatorial radius
J2_EARTH = 1.08262668e-3  # -
OMEGA_EARTH = 7.292115e-5  # rad/s
G0 = 9.80665  # m/s^2, standard gravity (rocket equation)
EGM96_SHIPPED_DEGREE = 120  # degree and order of the shipped EGM96 coefficients (proxops.environment.harmonics)
KARMAN_LINE_KM = 100.0  # km: below it drag ends an orbit within a revolution (scenario perigee floor, re-entry end of a run)
