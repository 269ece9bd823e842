"""knitsim.warp_runtime: the machine's resources as the package sees them."""
import os

import pytest

from knitsim import warp_runtime


@pytest.fixture
def no_cpu_quota(monkeypatch):
    """The machine's own control group left out (a CI runner may have a CPU quota): no quota."""
    monkeypatch.setattr(warp_runtime, "cgroup_cpu_limit", lambda root=None: None)


def test_usable_cores_are_the_process_affinity_not_the_hosts_count(monkeypatch, no_cpu_quota):
    # expectation: a container or batch job limited to 2 of a host's 64 cores reports 64 through os.cpu_count()
    # and {0, 1} through sched_getaffinity (Linux); the sweep's worker limit and Warp's parallel compile must use 2
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 64)
    monkeypatch.setattr(warp_runtime.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert warp_runtime.usable_cores() == 2


def test_usable_cores_fall_back_to_the_count_where_no_affinity_is_reported(monkeypatch, no_cpu_quota):
    # expectation: macOS and Windows have no os.sched_getaffinity; the host's count is then all there is
    monkeypatch.delattr(warp_runtime.os, "sched_getaffinity", raising=False)
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 6)
    assert warp_runtime.usable_cores() == 6
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: None)   # "undetermined" (os.cpu_count's docs)
    assert warp_runtime.usable_cores() == 1


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity on this system")
def test_the_sweeps_worker_limit_reads_the_affinity(monkeypatch, no_cpu_quota):
    # expectation: --workers 3 is more than a 2-core affinity even on a host that counts 64 cores
    from knitsim.errors import KnitsimInputError
    from knitsim.sweep import runner
    monkeypatch.setattr(warp_runtime.os, "cpu_count", lambda: 64)
    monkeypatch.setattr(warp_runtime.os, "sched_getaffinity", lambda pid: {0, 1})
    with pytest.raises(KnitsimInputError, match=r"more than the 2 core\(s\)"):
        runner.check_workers(3)
    runner.check_workers(2)


@pytest.mark.parametrize("files, expected", [
    # cgroup v2: "quota period" in microseconds; docker --cpus 2 writes "200000 100000"
    ({"cpu.max": "200000 100000\n"}, 2),
    ({"cpu.max": "150000 100000"}, 2),          # 1.5 cores' worth of time: two processes still get it all
    ({"cpu.max": "50000 100000"}, 1),           # half a core: one
    ({"cpu.max": "max 100000"}, None),          # no quota
    # cgroup v1: cpu/cpu.cfs_quota_us, -1 where unlimited
    ({"cpu/cpu.cfs_quota_us": "400000", "cpu/cpu.cfs_period_us": "100000"}, 4),
    ({"cpu/cpu.cfs_quota_us": "-1", "cpu/cpu.cfs_period_us": "100000"}, None),
    ({}, None),                                 # no control group files (macOS, Windows, a bare host)
    ({"cpu.max": "garbled"}, None),
])
def test_a_cgroup_cpu_quota_in_cores(tmp_path, files, expected):
    # expectation: the quota over the period, rounded up (the kernel's CFS bandwidth control: a quota of q us
    # per period of p us is q / p CPUs' worth of time), None where unlimited or unreadable
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    assert warp_runtime.cgroup_cpu_limit(tmp_path) == expected


def test_usable_cores_are_capped_by_the_cpu_quota(monkeypatch):
    # expectation: a container started with --cpus 2 on a 64-core host keeps all 64 in its affinity; the sweep's
    # worker limit and the test run's workers must count the 2 cores its quota gives it
    monkeypatch.setattr(warp_runtime.os, "sched_getaffinity", lambda pid: set(range(64)), raising=False)
    monkeypatch.setattr(warp_runtime, "cgroup_cpu_limit", lambda root=None: 2)
    assert warp_runtime.usable_cores() == 2
    monkeypatch.setattr(warp_runtime, "cgroup_cpu_limit", lambda root=None: 128)   # a quota above the affinity
    assert warp_runtime.usable_cores() == 64


def test_native_messages_are_silenced_where_sys_stderr_has_no_descriptor():
    """Warp's native library writes "Could not find or load the NVIDIA CUDA driver" to descriptor 2 at init.
    Under pytest's capture sys.stderr is an object without a descriptor: the silencer took that as "nothing to
    silence" and the message, caught by the capture, was printed at the end of every test run on a machine
    without CUDA.  Checked in a subprocess: a write to descriptor 2 inside the block, sys.stderr a StringIO."""
    import subprocess
    import sys

    code = ("import io, os, sys\n"
            "from knitsim import warp_runtime\n"
            "sys.stderr = io.StringIO()\n"
            "with warp_runtime._native_stderr_silenced():\n"
            "    os.write(2, b'native message\\n')\n"
            "os.write(2, b'after\\n')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr == "after\n"
