"""Yarn-to-yarn friction laws (float64 NumPy/SciPy references).

Modules
-------
capstan
    Capstan test of Dusserre (2015) section 2.4: eq 1 (drive-belt formula),
    the Howell power law Ft = a Fn^n integrated crossing by crossing (eqs 2-5),
    identification of (b, p, n) from capstan records (Table 3).
coiling
    Apparent tangent-to-normal ratio m at a crossing with coiling angle theta
    (eq 10) and the coiling angle of the jammed knit (eq 11).
dahl
    Dahl (1976) rate-independent friction state and its identification from a
    hysteresis loop (Gemtex KES bending paper).

The Warp twins used inside kernels live in :mod:`knitsim.kernels`.
"""
