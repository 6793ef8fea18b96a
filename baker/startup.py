"""Ctrl-C while a command is still starting (importing numba and the
kernels takes about a second): held until the command runs, which then
stops at once with its usual one line (cli.run), instead of a traceback
from inside the import machinery. Only for the `voxbake` / `voxview`
commands and `python -m baker`; a library user's process is left alone."""
import os
import signal
import sys
import threading

_held = []


def _note(signum, frame):
    _held.append(signum)


def is_command() -> bool:
    """Is this process one of our commands, still starting up? (While
    `python -m baker` imports the package, sys.argv[0] is '-m'.)"""
    name = os.path.basename(sys.argv[0]) if sys.argv else ""
    return name in ("voxbake", "voxview", "-m")


def hold_interrupts():
    if is_command() and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _note)


def release_interrupts() -> bool:
    """Puts Python's Ctrl-C handling back; True if Ctrl-C came meanwhile."""
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is _note:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    return bool(_held)
