"""knitsim: a batched simulator of technical knit patches.

The package is organised by physics:

- :mod:`knitsim.friction` -- yarn-to-yarn friction laws (capstan drive-belt law,
  coiling-angle ratio, Dahl hysteresis), float64 NumPy/SciPy references;
- :mod:`knitsim.kernels` -- the Warp device code (``@wp.func`` twins and kernels);
- :mod:`knitsim.cli` -- the ``knitsim`` command line.

Units inside the code: N, mm, s, rad.  Degrees only at the edges, named so.
"""

__version__ = "0.1.0"

from .errors import KnitsimInputError  # noqa: F401
