"""How many CPUs this process may keep busy: its affinity, or fewer where its control group's quota
allows less time. Asked by everything that starts workers (the frames' deforming processes, a batch's
local Ray), so that a container started with ``--cpus 1`` on a 16-core host is not given 16 workers
that only take turns, each holding its own working arrays."""

from __future__ import annotations

import math
import os
from pathlib import Path

__all__ = ["usable_cpus"]


def usable_cpus(cgroup_root: str = "/sys/fs/cgroup") -> int:
    """The CPUs this process may run on (its affinity), or fewer where its control group's CPU quota
    allows less time. The quota is read from cgroup v2 (``cpu.max``) or v1
    (``cpu/cpu.cfs_quota_us`` over ``cpu.cfs_period_us``) under ``cgroup_root``, for this process's
    own group (a limit set on a parent group is not seen), or at the root; none found, or unlimited,
    leaves the affinity.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as root:  # a cgroup v2 root allowing half a CPU
    ...     _ = (Path(root) / "cpu.max").write_text("50000 100000")
    ...     usable_cpus(root)
    1
    """
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    quota = _cpu_quota(cgroup_root)
    return max(1, min(usable, math.ceil(quota))) if quota is not None else usable


def _cpu_quota(cgroup_root: str) -> float | None:
    """CPUs' worth of time per second the process's control group allows; None if unlimited or unknown."""
    try:
        groups = [line.split(":", 2) for line in Path("/proc/self/cgroup").read_text().splitlines()]
    except OSError:
        groups = []
    # cgroup v2 lists one line "0::/path"; v1 a line per controller, "N:cpu,cpuacct:/path".
    v2 = [g[2] for g in groups if len(g) == 3 and g[:2] == ["0", ""]] + ["/"]
    v1 = [g[2] for g in groups if len(g) == 3 and "cpu" in g[1].split(",")] + ["/"]
    root = Path(cgroup_root)
    found = [(root / p.lstrip("/") / "cpu.max", None) for p in v2]
    found += [(root / "cpu" / p.lstrip("/") / "cpu.cfs_quota_us", root / "cpu" / p.lstrip("/") / "cpu.cfs_period_us")
              for p in v1]
    for quota_file, period_file in found:
        try:
            if period_file is None:  # v2: "QUOTA PERIOD", QUOTA "max" when unlimited
                quota, *period = quota_file.read_text().split()
                if quota == "max":
                    return None
                period = period[0]
            else:
                quota, period = quota_file.read_text().strip(), period_file.read_text().strip()
            quota, period = int(quota), int(period)
        except (OSError, ValueError, IndexError):
            continue
        return quota / period if quota > 0 and period > 0 else None
    return None
