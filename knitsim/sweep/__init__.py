"""Parameter sweeps of cell scenes (``knitsim sweep``).

:mod:`.spec` reads the ``[sweep]`` table (grid or Latin hypercube over any
scene key path); :mod:`.runner` validates every sample, runs chunks of
samples as single batched engine calls (in-process or on Dask), writes each
chunk as it finishes, resumes, and assembles an xarray Dataset;
:mod:`.plots` draws it.
"""
from .runner import SweepChunkError, SweepPlan, SweepRun, assemble, plan_sweep, run_sweep
from .spec import SweepParameter, SweepSpec, parse_sweep

__all__ = ["SweepSpec", "SweepParameter", "parse_sweep", "SweepPlan", "SweepRun", "SweepChunkError",
           "plan_sweep", "run_sweep", "assemble"]
