"""Stopping a run from outside: a `kill` or a hang-up taken as Ctrl-C (terminate_as_interrupt),
and the three held while a run is put in place (signals_held). Used by the command line, the
experiments and a script's Mission.run(out)."""
from __future__ import annotations

import contextlib


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP received within terminate_as_interrupt: stops as Ctrl-C does, named
    apart."""


STOPPING_SIGNALS = {
    "SIGTERM": "a kill, or a batch scheduler's time limit",
    "SIGHUP": "the terminal or the ssh session closed",
}


@contextlib.contextmanager
def _handlers_installed(names, handler, keep):
    """Within it, `handler` handles each signal of `names` that this platform has and whose
    handler on entry `keep` does not keep; the handlers there were are put back on leaving. Main
    thread only, where Python's handlers run: elsewhere it does nothing."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for name in names:
        signum = getattr(signal, name, None)  # (no SIGHUP on Windows)
        if signum is not None and not keep(signal.getsignal(signum)):
            previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, before in previous.items():
            signal.signal(signum, before)


@contextlib.contextmanager
def terminate_as_interrupt(only_default: bool = False):
    """Within it, a `kill` (SIGTERM: also what batch schedulers send at a time limit) or a
    hang-up (SIGHUP: the terminal or ssh session closed) raises Terminated, a
    KeyboardInterrupt, as Ctrl-C does: an experiment's workers stopped, finished runs kept, the
    partial table written; a single run's flight kept (recorder.fly_into), its summary's
    stopped_by naming the signal. A signal ignored on entry (`nohup` ignores SIGHUP) stays
    ignored; with only_default, so does one with a handler of its own (a script's). (Main
    thread only: signals go there; elsewhere it does nothing.)"""
    import signal

    def interrupt(signum, frame):
        name = signal.Signals(signum).name
        raise Terminated(f"{name} ({STOPPING_SIGNALS[name]})")

    def keep(now):
        return now is signal.SIG_IGN or (only_default and now is not signal.SIG_DFL)

    with _handlers_installed(STOPPING_SIGNALS, interrupt, keep):
        yield


@contextlib.contextmanager
def signals_held():
    """Ctrl-C, a kill and a hang-up held within it, and raised again on leaving it (with the
    handlers there were: a default one ends the process then). A run's results whole in its
    temporary folder are put in place whole: a script's kill during the renames ended the
    process there, leaving them in the temporary folder, which the next run on the target
    removes. (Main thread only, where Python's handlers run; a signal ignored stays ignored.)"""
    import signal

    pending = []
    try:
        with _handlers_installed(
            ("SIGINT", "SIGTERM", "SIGHUP"),
            lambda signum, frame: pending.append(signum),
            lambda now: now in (signal.SIG_IGN, None),
        ):
            yield
    finally:  # raised again whatever ended the body (an OSError placing the run too)
        for signum in dict.fromkeys(pending):
            signal.raise_signal(signum)
