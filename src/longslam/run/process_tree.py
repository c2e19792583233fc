"""What a run's whole process tree used, measured from outside the method: CPU time, the time its
threads waited for a CPU, and peak resident memory summed over the tree.

The wait is the kernel's per-thread run-queue delay: the second field of
`/proc/<pid>/task/<tid>/schedstat`, nanoseconds a thread was runnable but not running. A run whose
threads waited long was denied the CPU it needed (other work on the machine, or more threads than
cores), and its times and, for a real-time system, its results are not its own. A background
thread samples every thread of this process and of every descendant process; a thread or child
that ends between two samples keeps its last sample, so at most one interval of it is lost.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
from pathlib import Path

SAMPLE_INTERVAL_S = 0.2
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
# A run whose threads waited for more than this share of (wait + CPU) was starved of CPU.
STARVED_SHARE = 0.10


def starved(cpu_wait_share: float | None) -> bool:
    """Whether a run with this CPU wait share (None: not measured) was starved of CPU."""
    return (cpu_wait_share or 0.0) > STARVED_SHARE


def _read(path: str) -> str | None:
    try:
        with open(path) as handle:
            return handle.read()
    except OSError:  # the thread or process ended meanwhile, or no /proc
        return None


def _thread_schedstat(pid: int) -> dict[int, tuple[int, int]]:
    """tid -> (ns on a CPU, ns waiting on a run queue) for every thread of `pid`."""
    found: dict[int, tuple[int, int]] = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return found
    for tid in tids:
        text = _read(f"/proc/{pid}/task/{tid}/schedstat")
        if text:
            parts = text.split()
            found[int(tid)] = (int(parts[0]), int(parts[1]))
    return found


def _thread_name(pid: int, tid: int) -> str:
    text = _read(f"/proc/{pid}/task/{tid}/comm")
    return text.strip() if text else "?"


def _rss_bytes(pid: int) -> int:
    text = _read(f"/proc/{pid}/statm")
    return int(text.split()[1]) * PAGE_BYTES if text else 0


def descendants(pid: int) -> list[int]:
    """Every living process below `pid` (children, their children...)."""
    children: dict[int, list[int]] = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    for entry in entries:
        if not entry.isdigit():
            continue
        text = _read(f"/proc/{entry}/stat")
        if not text:
            continue
        # The command name may hold spaces and parentheses: fields start after the last ')'.
        ppid = int(text.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(entry))
    found, todo = [], list(children.get(pid, []))
    while todo:
        child = todo.pop()
        found.append(child)
        todo.extend(children.get(child, []))
    return found


@dataclass(frozen=True)
class TreeUsage:
    """What the process tree used between `TreeMonitor.start` and `stop`."""

    cpu_time_s: float  # on a CPU, every thread of the process and its descendants
    cpu_wait_s: float  # runnable but waiting for a CPU, the same threads
    peak_rss_bytes: int  # the largest sum of resident memory over the tree in one sample
    child_processes: int  # descendant processes seen
    samples: int
    # CPU and wait seconds by thread (`thread_labels`: a thread's `comm`, "python", "longslam-read",
    # a native system's own names, numbered in start order where a process's threads share one),
    # largest wait first: whose threads waited, the run's own or the harness's.
    by_thread: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def cpu_wait_share(self) -> float:
        """The wait over wait plus CPU time: 0 for a run that always had its CPU."""
        total = self.cpu_wait_s + self.cpu_time_s
        return self.cpu_wait_s / total if total > 0 else 0.0

    @property
    def starved(self) -> bool:
        return starved(self.cpu_wait_share)


class TreeMonitor:
    """Samples this process (or `pid`) and its descendants on a thread of its own.

    Usage: `monitor = TreeMonitor(); monitor.start(); ...; usage = monitor.stop()`. Thread time
    from before `start` is not counted, nor child processes already alive then (a test runner's,
    a multiprocessing helper's); the sampling thread itself is left out."""

    def __init__(self, pid: int | None = None, interval_s: float = SAMPLE_INTERVAL_S):
        self.pid = pid if pid is not None else os.getpid()
        self.interval_s = interval_s
        self._baseline: dict[tuple[int, int], tuple[int, int]] = {}
        self._latest: dict[tuple[int, int], tuple[int, int]] = {}
        self._children: set[int] = set()
        self._peak_rss = 0
        self._samples = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._own_tid: int | None = None
        self._lock = threading.Lock()
        self._before: set[int] = set()  # children alive before `start` are not the run's
        self._names: dict[tuple[int, int], str] = {}

    def _sample(self) -> None:
        pids = [self.pid, *(pid for pid in descendants(self.pid) if pid not in self._before)]
        rss = 0
        latest = {}
        for pid in pids:
            for tid, values in _thread_schedstat(pid).items():
                if tid != self._own_tid:
                    latest[(pid, tid)] = values
                    if (pid, tid) not in self._names:
                        self._names[(pid, tid)] = _thread_name(pid, tid)
            rss += _rss_bytes(pid)
        with self._lock:
            self._latest.update(latest)
            self._children.update(pids[1:])
            self._peak_rss = max(self._peak_rss, rss)
            self._samples += 1

    def _loop(self) -> None:
        self._own_tid = threading.get_native_id()  # the sampler's own time is no one's
        while not self._stop.wait(self.interval_s):
            self._sample()

    def start(self) -> "TreeMonitor":
        self._before = set(descendants(self.pid))
        self._baseline = {(self.pid, tid): v for tid, v in _thread_schedstat(self.pid).items()}
        self._sample()
        self._thread = threading.Thread(target=self._loop, name="longslam-tree-monitor", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> TreeUsage:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._sample()
        with self._lock:
            cpu_ns = wait_ns = 0
            named: dict[str, list[int]] = {}
            labels = thread_labels({key: self._names.get(key, "?") for key in self._latest})
            for key, (cpu, wait) in self._latest.items():
                base_cpu, base_wait = self._baseline.get(key, (0, 0))
                cpu_ns += max(0, cpu - base_cpu)
                wait_ns += max(0, wait - base_wait)
                totals = named.setdefault(labels[key], [0, 0])
                totals[0] += max(0, cpu - base_cpu)
                totals[1] += max(0, wait - base_wait)
            by_thread = {name: (c * 1e-9, w * 1e-9) for name, (c, w) in sorted(named.items(), key=lambda kv: -kv[1][1])}
            return TreeUsage(
                cpu_ns * 1e-9, wait_ns * 1e-9, self._peak_rss, len(self._children), self._samples, by_thread
            )


def thread_labels(names: dict[tuple[int, int], str]) -> dict[tuple[int, int], str]:
    """A label per (pid, tid): the thread's name, and where several threads of one process share a
    name (a native system's unnamed threads inherit the process's), the name with the thread's
    place in start order, `name#0` first: Linux hands out thread ids in increasing order, so #0
    is the process's main thread and the others follow in the order they were started."""
    groups: dict[tuple[int, str], list[int]] = {}
    for (pid, tid), name in names.items():
        groups.setdefault((pid, name), []).append(tid)
    labels = {}
    for (pid, name), tids in groups.items():
        for place, tid in enumerate(sorted(tids)):
            labels[(pid, tid)] = name if len(tids) == 1 else f"{name}#{place}"
    return labels


def schedstat_available() -> bool:
    """Whether this kernel reports per-thread run-queue delays (Linux with schedstat)."""
    return Path(f"/proc/{os.getpid()}/task/{threading.get_native_id()}/schedstat").is_file()
