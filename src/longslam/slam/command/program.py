"""Running one external program to its end, or to its timeout, in a process group of its own.

The program starts in a new session (`start_new_session`), so it and every process it starts
(unless one makes a session of its own) share a process group that can be killed at once: after a
timeout, after Ctrl-C or an error in longslam, and after the program exits, for whatever it left
running. Its stdout and stderr are appended to a log file; the last lines it printed go into the
error of a failed run. It runs as a child of the run's process, so the run engine's process-tree
monitor counts its memory, CPU and CPU wait.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from longslam.core.errors import MethodError

LAST_LINES = 5  # lines of the program's output quoted in a failed run's error
LINE_CHARS = 200  # longer lines are cut in that quote
TERM_GRACE_S = 3.0  # after SIGTERM at a timeout, the group gets this long before SIGKILL
POLL_S = (0.01, 0.2)  # first and longest interval between two looks at the program
TAIL_BYTES = 1 << 16  # of the program's output kept for messages


@dataclass(frozen=True)
class ProgramRun:
    """How a program ended."""

    exit_status: int  # its exit code; -N when signal N killed it
    wall_time_s: float
    cpu_time_s: float  # user + system, the program and the descendants it waited for
    max_rss_bytes: int  # the largest resident set of one process among them (not their sum)
    output: str  # the end of what it printed (stdout and stderr), decoded


def signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def last_lines(text: str, count: int = LAST_LINES) -> str:
    """The last `count` non-blank lines of `text`, on one line ("printed nothing" for none)."""
    lines = [line.strip() for line in text.replace("\r", "\n").splitlines() if line.strip()]
    if not lines:
        return "it printed nothing"
    shown = [line if len(line) <= LINE_CHARS else line[:LINE_CHARS] + "..." for line in lines[-count:]]
    return f"its last {'line' if len(shown) == 1 else f'{len(shown)} lines'}: " + " | ".join(shown)


def describe_status(status: int) -> str:
    if status < 0:
        return f"was killed by {signal_name(-status)} (signal {-status}, exit status {status})"
    return f"exited with exit status {status}"


def _exited(pid: int) -> bool:
    """Whether the child has ended, without reaping it: while it is a zombie its process group id
    cannot be taken by another process, so the group can still be killed safely."""
    return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None


def _signal_group(pgid: int, sig: int) -> bool:
    """Send `sig` to the process group; False when no process is left in it."""
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:
        return False
    except PermissionError:  # a member changed user: nothing we may do about it
        return False
    return True


def _wait_until(pid: int, deadline: float) -> bool:
    """Poll until the child ends (True) or `deadline` passes (False)."""
    interval = POLL_S[0]
    while not _exited(pid):
        now = time.monotonic()
        if now >= deadline:
            return False
        time.sleep(min(interval, deadline - now))
        interval = min(interval * 2, POLL_S[1])
    return True


def _read_from(path: Path, offset: int) -> str:
    """The end (at most TAIL_BYTES) of what `path` holds after `offset`."""
    try:
        with open(path, "rb") as handle:
            handle.seek(max(offset, handle.seek(0, os.SEEK_END) - TAIL_BYTES))
            return handle.read().decode("utf-8", errors="replace")
    except OSError:
        return ""


def run_program(argv: list[str], cwd: Path, log: Path, timeout: float, what: str) -> ProgramRun:
    """Run `argv` in `cwd`, its output appended to `log`, and wait for it. MethodError (one line:
    how it ended and the last lines it printed) when it cannot start, exits non-zero, is killed
    by a signal or outlives `timeout` seconds (then its whole process group is killed).
    `what` names the method in messages."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "ab") as handle:
        offset = handle.tell()
        t0 = time.monotonic()
        try:
            proc = subprocess.Popen(
                argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=handle, stderr=subprocess.STDOUT, start_new_session=True
            )
        except OSError as err:
            raise MethodError(f"{what}: cannot start {argv[0]!r}: {err.strerror or err}") from None
    pid, reaped, timed_out = proc.pid, False, False
    try:
        if not _wait_until(pid, t0 + timeout):
            timed_out = True
            _signal_group(pid, signal.SIGTERM)
            _wait_until(pid, time.monotonic() + TERM_GRACE_S)
        # Whatever is left of the group (everything, after a timeout; background processes the
        # program left behind, after an exit) is killed while the leader still holds the group id.
        _signal_group(pid, signal.SIGKILL)
        _, status, usage = os.wait4(pid, 0)
        reaped = True
        proc.returncode = os.waitstatus_to_exitcode(status)
    finally:
        if not reaped:  # an error or Ctrl-C in longslam: the program must not outlive the run
            _signal_group(pid, signal.SIGKILL)
            try:
                os.wait4(pid, 0)
                proc.returncode = -signal.SIGKILL
            except ChildProcessError:
                pass
    wall = time.monotonic() - t0
    output = _read_from(log, offset)
    if timed_out:
        raise MethodError(
            f"{what}: {argv[0]!r} ran past its timeout of {timeout:g} s and was killed with every "
            f"process it started; {last_lines(output)}"
        )
    if proc.returncode != 0:
        raise MethodError(
            f"{what}: {argv[0]!r} {describe_status(proc.returncode)} after {wall:.1f} s; " f"{last_lines(output)}"
        )
    return ProgramRun(proc.returncode, wall, usage.ru_utime + usage.ru_stime, int(usage.ru_maxrss) * 1024, output)
