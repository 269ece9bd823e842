"""One entry point for every cell engine: :func:`simulate`.

``"warp"``: the batched Warp kernels (:func:`knitsim.cell.batch.run_batch`),
imported lazily so that the NumPy reference works without them.
``"reference"``: the float64 NumPy reference, one cell at a time
(:func:`knitsim.cell.cycle.run_cell`).  Both return a
:class:`~knitsim.cell.history.BatchHistory`.
"""
from __future__ import annotations

from typing import Callable

from ..errors import KnitsimInputError
from .history import BatchHistory
from .load_program import LoadProgram

ENGINES = ("warp", "reference")


def check_engine(engine: str) -> Callable:
    """The run function of ``engine``; refuses an unknown or unavailable engine.

    Raises
    ------
    KnitsimInputError
        ``engine`` is not one of :data:`ENGINES`, or the Warp batch engine
        cannot be imported.
    """
    if engine == "reference":
        from .cycle import run_cells_reference
        return run_cells_reference
    if engine == "warp":
        try:
            from .. import warp_runtime
            warp_runtime.init()          # quiet, stable kernel cache: before any kernel module loads
            from .batch import run_batch
        except ImportError as exc:
            raise KnitsimInputError(f"engine 'warp' is not available ({exc}); use engine = \"reference\"") from None
        return run_batch
    raise KnitsimInputError(f"engine = {engine!r}: expected one of {', '.join(ENGINES)}")


def simulate(params: list, program: LoadProgram, engine: str = "warp", device: str = "cpu",
             progress: Callable | None = None) -> BatchHistory:
    """Run cells through a load program.

    Parameters
    ----------
    params : list of CellParams
        The cells (validated by the engine before any solve).
    program : LoadProgram
        The imposed strains of the course length, shared by every cell.
    engine : {"warp", "reference"}
        Batched Warp kernels, or the NumPy reference.
    device : str
        Warp device (``"cpu"``, ``"cuda"``, ``"cuda:N"``, ``"auto"``); the
        reference always runs on the CPU.
    progress : callable, optional
        Called as the run advances: the Warp engine passes it on to
        :func:`~knitsim.cell.batch.run_batch` (``progress(done_increments, n)``, all cells at once); the
        reference, one cell after the other, calls ``progress(done, n_cells x n_increments)`` after each
        increment of each cell.

    Returns
    -------
    BatchHistory
    """
    run = check_engine(engine)
    params = list(params)
    if engine == "warp":
        from .. import warp_runtime
        return run(params, program, device=warp_runtime.resolve_device(device), progress=progress)
    from .cycle import run_cell
    histories = []
    m, total = len(program), len(params) * len(program)
    for i, p in enumerate(params):
        tick = None if progress is None else (lambda k, before=i * m: progress(before + k, total))
        histories.append(run_cell(p, program, progress=tick))
    return BatchHistory.stack(histories)
