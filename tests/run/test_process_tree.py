"""The CPU a run was denied and its process tree's memory, measured from outside (run/process_tree.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from longslam.run.process_tree import TreeMonitor, descendants, schedstat_available

# Under xdist, --dist loadfile (the README's command) keeps these tests, which pin this process to
# one core and measure its wait, in one worker, one after another rather than side by side there.
pytestmark = pytest.mark.skipif(not schedstat_available(), reason="needs Linux per-thread schedstat")

BUSY = "import time\nend = time.time() + {s}\nwhile time.time() < end: pass\n"
HOLD = "import time\nblock = bytearray({n})\nblock[::4096] = b'x' * len(block[::4096])\ntime.sleep({s})\n"


def _busy(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def _busy_cpu(seconds: float, timeout_s: float = 20.0) -> None:
    """Spin until this thread has used `seconds` of CPU (or `timeout_s` of wall time passed)."""
    start, end = time.thread_time(), time.monotonic() + timeout_s
    while time.thread_time() - start < seconds and time.monotonic() < end:
        pass


@pytest.fixture
def one_core():
    """This process pinned to one core (the children it starts inherit it), restored after."""
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(before)})
    yield
    os.sched_setaffinity(0, before)


def _core_busy_s(core: int) -> float:
    """Seconds the core has spent on any task (not idle, not waiting on I/O) since boot."""
    with open("/proc/stat") as stat:
        for line in stat:
            if line.startswith(f"cpu{core} "):
                user, nice, system, _idle, _iowait, irq, softirq, steal = map(int, line.split()[1:9])
                return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")
    raise AssertionError(f"no cpu{core} in /proc/stat")


def test_a_run_alone_on_its_core_waits_little(one_core):
    """A run alone needs a core nobody else wants: what the core ran besides this test is measured, and a
    try in which others used the core (another test worker, another session's work) is tried again;
    if the core is never free, the test is skipped, since the wait measured is then the load's,
    which is the starved test's subject."""
    core = min(os.sched_getaffinity(0))
    for _ in range(5):
        before = _core_busy_s(core)
        usage = TreeMonitor().start()
        _busy(0.6)
        usage = usage.stop()
        others = _core_busy_s(core) - before - usage.cpu_time_s
        if others < 0.1:
            break
        time.sleep(0.5)
    else:
        pytest.skip(f"core {core} was never free: others used {others:.2f} s of it during a 0.6 s try")
    assert usage.cpu_time_s >= 0.4
    # Other work on a shared machine may take a little; a starved run waits about as long as it runs.
    assert usage.cpu_wait_share < 0.3


def _wait_until_running(processes: list, timeout_s: float = 10.0) -> None:
    """Until each process has used some CPU: on a loaded machine an interpreter takes a while to start."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        used = [int(open(f"/proc/{p.pid}/schedstat").read().split()[0]) for p in processes]
        if min(used) > 50_000_000:  # ns: past start-up, in the busy loop
            return
        time.sleep(0.05)
    raise AssertionError("the busy processes did not start")


def test_a_run_beside_two_busy_processes_on_its_core_is_marked_starved(one_core):
    hogs = [subprocess.Popen([sys.executable, "-c", BUSY.format(s=30.0)]) for _ in range(2)]
    try:
        _wait_until_running(hogs)
        monitor = TreeMonitor().start()
        # 0.4 s of this thread's own CPU (about 1.2 s of wall time beside the two): counted in CPU,
        # not wall time, so that a machine loaded besides (another worker, another session) cannot
        # leave this thread too little CPU to measure.
        _busy_cpu(0.4)
        usage = monitor.stop()
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    # Three busy processes on one core: this one runs about a third of the time.
    assert usage.cpu_wait_share >= 0.4, usage
    # The wait is this thread's (pytest's main thread is named after its program).
    name, (cpu, wait) = next(iter(usage.by_thread.items()))
    assert wait >= 0.5 and cpu >= 0.2, usage.by_thread
    assert usage.starved
    assert usage.cpu_wait_s >= 0.5


def test_the_peak_sums_the_tree_and_child_processes_are_counted():
    monitor = TreeMonitor(interval_s=0.05).start()
    own = monitor._peak_rss
    child = subprocess.Popen([sys.executable, "-c", HOLD.format(n=200 * 2**20, s=1.0)])
    time.sleep(0.2)
    assert child.pid in descendants(os.getpid())
    child.wait()
    usage = monitor.stop()
    assert usage.child_processes >= 1
    assert usage.peak_rss_bytes >= own + 180 * 2**20
    # The child's CPU (it touched 200 MB) is the tree's too.
    assert usage.cpu_time_s > 0.0


def test_thread_time_from_before_start_is_not_counted():
    _busy(0.5)
    monitor = TreeMonitor().start()
    usage = monitor.stop()
    assert usage.cpu_time_s < 0.3


def test_children_alive_before_the_run_are_not_the_runs():
    earlier = subprocess.Popen([sys.executable, "-c", HOLD.format(n=100 * 2**20, s=2.0)])
    try:
        time.sleep(0.3)
        monitor = TreeMonitor(interval_s=0.05).start()
        time.sleep(0.3)
        usage = monitor.stop()
    finally:
        earlier.kill()
        earlier.wait()
    assert usage.child_processes == 0 and usage.peak_rss_bytes < monitor._peak_rss + 50 * 2**20


def test_threads_sharing_a_name_are_numbered_in_start_order_and_a_unique_name_stays_as_it_is():
    from longslam.run.process_tree import thread_labels

    # A native system's unnamed threads inherit the process's name; thread ids grow in start order.
    names = {(10, 12): "longslam", (10, 10): "longslam", (10, 15): "longslam", (10, 11): "longslam-read",
             (20, 21): "longslam"}
    assert thread_labels(names) == {(10, 10): "longslam#0", (10, 12): "longslam#1", (10, 15): "longslam#2",
                                    (10, 11): "longslam-read", (20, 21): "longslam"}
