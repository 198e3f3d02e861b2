"""Process helpers shared by the benchmarks that watch a running graph (flagship, soak): its node
processes, their CPU time and resident memory, read from ``/proc`` (Linux)."""

from __future__ import annotations

import os
from pathlib import Path

TICK = os.sysconf("SC_CLK_TCK")


def descendants(pid: int) -> list[int]:
    """Every process below ``pid``."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            children = Path(f"/proc/{p}/task/{p}/children").read_text().split()
        except OSError:
            continue
        out += [int(c) for c in children]
        todo += [int(c) for c in children]
    return out


def cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of a process (None once it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / TICK


def memory_mb(pid: int) -> tuple[float, float] | None:
    """Resident set size and its anonymous (private heap) part in MB, or None once the process is gone.

    The rest of the RSS is mapped files, mostly shared libraries: a process forked from the zygote
    maps their pages on first use, so its file part grows while it runs new code paths."""
    try:
        fields = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
        return int(fields["VmRSS"].split()[0]) / 1024, int(fields["RssAnon"].split()[0]) / 1024
    except (OSError, KeyError, ValueError):
        return None


def unit_name(pid: int) -> str:
    """The node ids a runner process hosts (its ``--nodes`` argument), ``zygote`` or ``launcher``.

    A node process forked by the zygote shows its command line as one title (spaces, not NULs)."""
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode().split()
    except OSError:
        return str(pid)
    if "--nodes" in argv:
        return argv[argv.index("--nodes") + 1]
    return "zygote" if "handflow.framework.runtime.zygote" in argv else "launcher"
