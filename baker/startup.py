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

`run` is how every command runs: one-line errors, these signals, warnings
as one line each.
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


def checkpoint():
    """Raises KeyboardInterrupt here if Ctrl-C was noted: call it where
    stopping leaves nothing half-done."""
    if _held:
        _held.clear()
        raise KeyboardInterrupt


def interrupted(exc: BaseException) -> bool:
    """Was this exception caused by Ctrl-C? numba's dispatcher, interrupted
    while it converts arguments, raises a SystemError whose context is the
    KeyboardInterrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def run(func, *args):
    """Calls func(*args) the way every voxgi command runs: one-line errors
    with exit 2, Ctrl-C with exit 130, our warnings as one line each (other
    libraries' warnings shown as usual), the process's warning hooks put
    back after."""
    import warnings
    from .errors import VoxgiError, VoxgiWarning
    original = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, VoxgiWarning):
            print(f"warning: {message}", file=sys.stderr)
        else:
            original(message, category, filename, lineno, file, line)
    with warnings.catch_warnings():
        warnings.showwarning = show
        try:
            checkpoint()  # Ctrl-C while the command was starting
            return func(*args)
        except VoxgiError as e:
            print(f"error: {e.one_line()}", file=sys.stderr)
            return 2
        except MemoryError:
            print("error: out of memory (lower --resolution or --memory-budget)", file=sys.stderr)
            return 2
        except OSError as e:  # an output or input the system refused (a full disk, a permission)
            if isinstance(e, BrokenPipeError):  # the output's reader left (`voxbake scenes | head -1`): quietly
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                return 141
            where = f"{e.filename}: " if e.filename else ""
            print(f"error: {where}{e.strerror or type(e).__name__}", file=sys.stderr)
            return 2
        except BaseException as e:
            if interrupted(e):
                print("interrupted: nothing was written", file=sys.stderr)
                return exit_status()
            raise
        finally:
            _ignore_while_exiting()


def _ignore_while_exiting():
    """The command's work is over (its files written or removed): a Ctrl-C
    or SIGTERM from here to the exit is ignored. Python's finalization puts
    SIG_DFL back in place of a Python handler (not of SIG_IGN), and a signal
    landing in that window would kill the process by the signal (exit -2,
    neither 0 nor 130)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) is _note:
            signal.signal(signum, signal.SIG_IGN)
