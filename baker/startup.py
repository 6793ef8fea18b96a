"""Ctrl-C and SIGTERM in the commands, answered only where it is safe to stop.

A KeyboardInterrupt raised at an arbitrary moment can land inside numba's
dispatcher (a SystemError chained to it) or inside a C callback of
llvmlite's compiler cache (where Python prints it and carries on, and the
process later dies of SIGINT). So the `voxbake` / `voxview` commands (and
`python -m baker`) note Ctrl-C instead, from the first import on, and the
work stops at its next checkpoint (`checkpoint()`: between photon batches,
image bands, propagation calls, voxelization steps, stages): the command
then prints its one line and exits 130. A second Ctrl-C stops at once.
SIGTERM (what `timeout`, systemd and docker send) is answered the same way,
with exit status 143. A library user's process is left alone: its Ctrl-C
behaves as Python's.
"""
import os
import signal
import sys
import threading

_held = []
_last = [signal.SIGINT]  # the signal that stopped the command: its exit status is 128 + this


def _note(signum, frame):
    _last[0] = signum
    if _held:  # a second Ctrl-C: the user insists, stop now
        raise KeyboardInterrupt
    _held.append(signum)


def exit_status() -> int:
    """The exit status of a command stopped by a signal: 130 for Ctrl-C,
    143 for SIGTERM."""
    return 128 + int(_last[0])


def is_command() -> bool:
    """Is this process one of our commands? (While `python -m baker`
    imports the package, sys.argv[0] is '-m'.)"""
    name = os.path.basename(sys.argv[0]) if sys.argv else ""
    return name in ("voxbake", "voxview", "-m")


def hold_interrupts():
    """In a command's main thread, Ctrl-C is noted, not raised."""
    if is_command() and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _note)
        signal.signal(signal.SIGTERM, _note)


def release_interrupts():
    """Puts Python's own Ctrl-C handling back."""
    if threading.current_thread() is threading.main_thread():
        if signal.getsignal(signal.SIGINT) is _note:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if signal.getsignal(signal.SIGTERM) is _note:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def checkpoint():
    """Raises KeyboardInterrupt here if Ctrl-C was noted: call it where
    stopping leaves nothing half-done."""
    if _held:
        _held.clear()
        raise KeyboardInterrupt
