"""CORTEX reference generation and the reference of its tracking loop (Wijayatunga et al. §3.1-3.4).

- :mod:`.config`     Table 2 parameters (CortexConfig), Fibonacci docking axes (no solver)
- :mod:`.holds`      sunlight-aware hold times (eqs. 13-15, Algorithm 1) on a sampled profile
- :mod:`.phases`     the convex phases CP1 (fly-around, KOS planes) and CP2 (cone, plume SCP)
- :mod:`.reference`  the outer problem (eq. 12), plan checks
- :mod:`.timeline`   the tracking loop's reference (segments, exact CW states), the safe orbit of §3.4
- :mod:`.replanner`  regeneration and retreat plans called from the loop
"""
