"""What a command will cost, said before it starts: memory checked against what the machine has,
and the expected time and disk use of long runs from measured per-unit costs.

The per-unit costs are measured on the 2-core development machine (``benchmarks/costs.py`` prints
them again); they are estimates to plan with, not promises (a loaded machine is slower).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

from .errors import UsageError

__all__ = [
    "available_memory_bytes",
    "address_space_left_bytes",
    "check_memory",
    "CostEstimate",
    "say_cost",
    "fmt_bytes",
    "fmt_seconds",
    "episode_cpu_s",
    "lockstep_episode_cpu_s",
    "ENV_EPISODE_CPU_S",
    "AGENT_EPISODE_CPU_S",
    "RAW_BYTES_PER_SAMPLE",
    "RAW_CPU_S_PER_SAMPLE",
]

# CPU seconds per 300 s episode (one decision per second, batches of 32) on the development machine: the
# environment (simulation and observation features, the reference diagnoser's conclusion included) and, on top,
# each agent's decisions; `python benchmarks/costs.py --json` (0.082 s at load 6, rounded up)
ENV_EPISODE_CPU_S = 0.09
AGENT_EPISODE_CPU_S = {
    "null": 0.0,
    "random": 0.0,
    "oracle": 0.0,
    "reference": 0.001,
    "sequential": 0.002,
    "ppo-v1": 0.01,
    "classifier-v1": 0.01,
    "classifier": 0.01,
    "classifier-v1+reference": 0.01,
}
RAW_BYTES_PER_SAMPLE = 382  # export-raw: bytes written per 100 Hz sample (sensor rows and ground truth)
RAW_CPU_S_PER_SAMPLE = 1.0e-5  # export-raw: CPU seconds per 100 Hz sample (simulating and writing the CSV rows)


def episode_cpu_s(agent: str, duration_s: float = 300.0) -> float:
    """Expected CPU seconds of one episode of ``agent`` (a name; any other agent is costed as the
    dearest named one)."""
    return lockstep_episode_cpu_s([agent], 1, duration_s)


def lockstep_episode_cpu_s(agents: list[str], passes: int, duration_s: float = 300.0) -> float:
    """Expected CPU seconds of one episode scored for every agent of ``agents``: the environment once per
    simulation pass (agents asking for the same diagnoser share one), each agent's own decisions on top."""
    own = sum(AGENT_EPISODE_CPU_S.get(a, max(AGENT_EPISODE_CPU_S.values())) for a in agents)
    return (ENV_EPISODE_CPU_S * passes + own) * duration_s / 300.0


def available_memory_bytes() -> int | None:
    """Memory the machine can give a new allocation now (``MemAvailable`` of /proc/meminfo), else the
    physical memory, else None when neither is known."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, OSError, ValueError):
        return None


def fmt_bytes(n: float) -> str:
    for unit, k in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= k:
            return f"{n / k:.3g} {unit}"
    return f"{n:.0f} B"


def fmt_seconds(s: float) -> str:
    if s >= 5400:
        return f"{s / 3600:.1f} h"
    if s >= 90:
        return f"{s / 60:.0f} min"
    return f"{s:.0f} s"


def address_space_left_bytes() -> int | None:
    """What this process may still map under its address-space limit (``RLIMIT_AS``, ``ulimit -v``): the
    limit less the address space in use (``VmSize`` of /proc/self/status); None without a limit."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError, AttributeError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = 0
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    used = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    return max(0, int(soft) - used)


def check_memory(need_bytes: float, what: str, option: str) -> None:
    """A :class:`UsageError` naming ``option`` and the limit when ``need_bytes`` exceed the memory
    available (the machine's, or less under the process's address-space limit), before anything is
    allocated."""
    machine, limit = available_memory_bytes(), address_space_left_bytes()
    if limit is not None and (machine is None or limit < machine):
        have, where = limit, "left under this process's address-space limit (ulimit -v)"
    else:
        have, where = machine, "available"
    if have is not None and need_bytes > have:
        raise UsageError(
            f"{option}: {what} needs about {fmt_bytes(need_bytes)} of memory, more than the "
            f"{fmt_bytes(have)} {where}; ask for less"
        )


@dataclass(frozen=True)
class CostEstimate:
    """A long run's expected cost: CPU time [s] (spread over ``workers``) and disk [bytes]."""

    cpu_s: float
    disk_bytes: float = 0.0
    workers: int = 1

    @property
    def wall_s(self) -> float:
        return self.cpu_s / max(1, min(self.workers, os.cpu_count() or 1))


def say_cost(prog: str, what: str, cost: CostEstimate, *, min_wall_s: float = 60.0) -> None:
    """One line on stderr with the expected time (and disk use) of a run expected to last at least
    ``min_wall_s``, or to write at least 100 MB."""
    if cost.wall_s < min_wall_s and cost.disk_bytes < 1e8:
        return
    disk = f", writes about {fmt_bytes(cost.disk_bytes)}" if cost.disk_bytes else ""
    workers = f" with {cost.workers} workers" if cost.workers > 1 else ""
    print(
        f"{prog}: {what}: expect about {fmt_seconds(cost.wall_s)}{workers}{disk} (estimated from measured "
        "per-unit costs; longer on a loaded machine)",
        file=sys.stderr,
    )
