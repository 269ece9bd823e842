"""knitsim.warp_runtime: the machine's resources as the package sees them."""
import os

import pytest

from knitsim import warp_runtime


def test_usable_cores_are_the_process_affinity_not_the_hosts_count(monkeypatch):
    # expectation: a container or batch job limited to 2 of a host's 64 cores reports 64 through os.cpu_count()
    # and {0, 1} through sched_getaffinity (Linux); the sweep's worker limit and Warp's parallel compile must use 2
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 64)
    monkeypatch.setattr(warp_runtime.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert warp_runtime.usable_cores() == 2


def test_usable_cores_fall_back_to_the_count_where_no_affinity_is_reported(monkeypatch):
    # expectation: macOS and Windows have no os.sched_getaffinity; the host's count is then all there is
    monkeypatch.delattr(warp_runtime.os, "sched_getaffinity", raising=False)
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 6)
    assert warp_runtime.usable_cores() == 6
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: None)   # "undetermined" (os.cpu_count's docs)
    assert warp_runtime.usable_cores() == 1


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity on this system")
def test_the_sweeps_worker_limit_reads_the_affinity(monkeypatch):
    # expectation: --workers 3 is more than a 2-core affinity even on a host that counts 64 cores
    from knitsim.errors import KnitsimInputError
    from knitsim.sweep import runner
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 64)
    monkeypatch.setattr(warp_runtime.os, "sched_getaffinity", lambda pid: {0, 1})
    with pytest.raises(KnitsimInputError, match=r"more than the 2 core\(s\)"):
        runner.check_workers(3)
    runner.check_workers(2)
