"""One place to initialise Warp and pick the device.

Warp compiles kernels on first use and caches the binaries.  The cache lives
outside the repository: ``$KNITSIM_KERNEL_CACHE`` if set, else Warp's own
``$WARP_CACHE_PATH``, else ``~/.cache/knitsim/warp``.  It is never cleared by
knitsim, so tests and runs after the first reuse compiled kernels.
"""
from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import warp as wp

from .errors import KnitsimInputError

_initialised = False


def kernel_cache_dir() -> Path:
    """The directory Warp caches compiled kernels in."""
    env = os.environ.get("KNITSIM_KERNEL_CACHE") or os.environ.get("WARP_CACHE_PATH")
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "knitsim" / "warp"


#: where a Linux container's control group says how much CPU time it may use (cgroup v2 at its root,
#: cgroup v1 under cpu/)
CGROUP_ROOT = Path("/sys/fs/cgroup")


def cgroup_cpu_limit(root: Path = CGROUP_ROOT) -> int | None:
    """The cores a CPU quota of the process's control group amounts to (its quota over its period, rounded
    up), or None where none is set or none can be read.

    A container started with ``--cpus 2`` (Docker, Kubernetes limits, a CI runner) keeps every core of its
    host in its affinity and in ``os.cpu_count()``; only the quota says it gets two cores' worth of time:
    ``cpu.max`` = "quota period" in cgroup v2 ("max" where unlimited), ``cpu.cfs_quota_us`` (-1 where
    unlimited) and ``cpu.cfs_period_us`` in cgroup v1."""
    def read(path: Path) -> str | None:
        try:
            return path.read_text().strip()
        except OSError:
            return None

    quota = period = None
    v2 = read(root / "cpu.max")
    if v2 is not None:
        parts = v2.split()
        if len(parts) == 2 and parts[0] != "max":
            quota, period = parts
    else:
        q, per = read(root / "cpu" / "cpu.cfs_quota_us"), read(root / "cpu" / "cpu.cfs_period_us")
        if q is not None and per is not None:
            quota, period = q, per
    try:
        q, per = int(quota), int(period)
    except (TypeError, ValueError):
        return None
    if q <= 0 or per <= 0:
        return None
    return max(1, -(-q // per))


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity where the system reports one (a container or a
    batch job limited to a few cores reports the host's count through ``os.cpu_count()``), else
    ``os.cpu_count()``; fewer where its control group's CPU quota allows fewer (:func:`cgroup_cpu_limit`)."""
    try:
        cores = max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):    # (macOS and Windows have no sched_getaffinity)
        cores = max(1, os.cpu_count() or 1)
    quota = cgroup_cpu_limit()
    return cores if quota is None else min(cores, quota)


def init() -> None:
    """Initialise Warp once, quietly, with the stable kernel cache."""
    global _initialised
    if _initialised:
        return
    # silence the start-up banner and module-load messages (stdout stays clean
    # for --json output); Warp >= 1.10 uses log_level, older releases quiet
    if hasattr(wp.config, "log_level"):
        wp.config.log_level = getattr(wp, "LOG_WARNING", 30)
    else:  # pragma: no cover
        wp.config.quiet = True
    wp.config.kernel_cache_dir = str(kernel_cache_dir())
    # Warp's native library prints "Could not find or load the NVIDIA CUDA driver" on a machine without
    # one; a CPU run must not see it.  A run that asks for CUDA gets knitsim's own error instead
    # (resolve_device), so nothing the user needs is lost.
    with _native_stderr_silenced():
        wp.init()
    _initialised = True


@contextlib.contextmanager
def _native_stderr_silenced():
    """Redirect file descriptor 2 to /dev/null for the block (C code writes there, not to sys.stderr).

    Descriptor 2 itself, whatever sys.stderr is: under pytest's capture sys.stderr is an object without a
    descriptor, and the driver's message went to the capture's file, printed at the end of every test run."""
    try:
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):
        pass
    fd = 2
    try:
        os.fstat(fd)
    except OSError:                                 # no descriptor 2 (a daemon with it closed)
        yield
        return
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


def preload(modules, device: str) -> None:
    """Compile (or fetch from the kernel cache) several Warp modules at once, in parallel threads.

    Warp compiles a module on its first launch, one module at a time.  A batch that mixes kernel keys
    launches one module per key (:mod:`knitsim.kernels.specialise`); on CUDA each takes NVRTC tens of
    seconds to a minute on a cold cache, so loading them together (NVRTC and LLVM run outside the GIL)
    cuts a first run's wait by about the number of cores.  Modules already loaded cost nothing.

    Parameters
    ----------
    modules : iterable of Python modules holding Warp code (or Warp modules)
    device : str
        A Warp device alias (see :func:`resolve_device`).
    """
    init()
    mods = []
    for m in modules:
        wm = m if isinstance(m, wp.Module) else wp.get_module(m.__name__)
        if wm not in mods:
            mods.append(wm)
    if mods:
        wp.force_load(device=device, modules=mods, max_workers=max(1, min(len(mods), usable_cores())))


def cuda_available() -> bool:
    """Whether a CUDA device can run kernels."""
    init()
    return wp.get_cuda_device_count() > 0


def available_devices() -> list[str]:
    """``["cpu"]`` plus ``"cuda:0"`` when a GPU is present."""
    init()
    return ["cpu"] + (["cuda:0"] if cuda_available() else [])


def resolve_device(name: str | None = "cpu") -> str:
    """Validate a device name from a scene or the command line.

    Parameters
    ----------
    name : str or None
        ``"cpu"`` (default), ``"cuda"``, ``"cuda:N"`` or ``"auto"`` (CUDA when
        present, else CPU).

    Returns
    -------
    str
        A Warp device alias.
    """
    init()
    if name in (None, "", "cpu"):
        return "cpu"
    if name == "auto":
        return "cuda:0" if cuda_available() else "cpu"
    if name == "cuda" or (isinstance(name, str) and name.startswith("cuda:")):
        if not cuda_available():
            raise KnitsimInputError(f"device = {name!r}: no CUDA device is available here (use 'cpu' or 'auto')")
        return "cuda:0" if name == "cuda" else name
    raise KnitsimInputError(f"device = {name!r}: expected 'cpu', 'cuda', 'cuda:N' or 'auto'")
