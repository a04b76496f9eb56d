"""Locks on files (POSIX ``flock``): ``FileLock``, an exclusive lock whose file its holder
removes, and ``RunLock``, a run folder's (``.<name>.lock`` beside it: nbvkit.runfolder)."""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path


def _lock_path(path: Path) -> Path:
    return path.parent / f".{path.name}.lock"


def _holder_named(pid: bytes) -> str:
    """'pid N' from the pid its holder wrote in a lock file, or "another process"."""
    text = pid.decode("ascii", "replace").strip()
    return f"pid {text}" if text.isdigit() else "another process"


def _open_lock(lp: Path, flags: int) -> int:
    """os.open of the lock file `lp`, without blocking: ValueError naming it where it is not a
    regular file (a FIFO in its place would block the open, and every reader, forever)."""
    fd = os.open(lp, flags | os.O_NONBLOCK, 0o644)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise ValueError(f"the lock file {lp} is not a regular file (nbvkit writes one): remove it")
    return fd


def lock_holder(path: Path) -> str | None:
    """'pid N' of the live process holding path's run lock, or None."""
    import fcntl

    lp = _lock_path(path)
    try:
        fd = _open_lock(lp, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return _holder_named(os.pread(fd, 64, 0))
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


class FileLock:
    """An exclusive advisory lock (POSIX ``flock``) on the file `path`, created for it and
    removed by its holder before it lets go, so that no lock file stays behind. The holder's
    pid is written in it (for messages). `acquire(wait=False)` returns False at once when
    another process holds it. A process that opened the file before the holder removed it
    finds, once it has the lock, that the name now leads elsewhere (or nowhere) and tries
    again on the name: two processes never hold two different files of one name."""

    def __init__(self, path):
        self.path = Path(path)
        self.fd: int | None = None

    def acquire(self, wait: bool = True) -> bool:
        import fcntl

        while True:
            fd = _open_lock(self.path, os.O_RDWR | os.O_CREAT)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
            except OSError as e:
                os.close(fd)
                if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                    return False
                raise
            try:
                held, named = os.fstat(fd), os.stat(self.path)
                same = (held.st_dev, held.st_ino) == (named.st_dev, named.st_ino)
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.pwrite(fd, str(os.getpid()).encode(), 0)
                self.fd = fd
                return True
            os.close(fd)  # removed by its holder meanwhile: lock the name again

    def holder(self) -> str:
        """'pid N' of the process holding the lock, as written in its file."""
        try:
            return _holder_named(self.path.read_bytes()[:64])
        except OSError:
            return _holder_named(b"")

    def release(self) -> None:
        import fcntl

        if self.fd is not None:
            try:
                self.path.unlink(missing_ok=True)  # while held: see the class's note
            except OSError:
                pass
            fcntl.flock(self.fd, fcntl.LOCK_UN)
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        self.acquire(wait=True)
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def pid_alive(pid: int, but: int | None = None) -> bool:
    """Whether the process `pid` lives (another user's too), `but` counted as gone: the owner
    of a temporary folder named by its pid that a killed process left."""
    if pid == but:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def folder_lock(path) -> FileLock:
    """The lock a run takes on its folder `path` (RunLock's file), for a change to a finished
    run's files: two exports updating one run's report take turns."""
    return FileLock(_lock_path(Path(path)))


class RunLock:
    def __init__(self, path: Path, what: str, wait: bool):
        self.path, self.what, self.wait = path, what, wait
        self.lock = FileLock(_lock_path(path))

    def acquire(self) -> None:
        try:
            got = self.lock.acquire(wait=self.wait)
        except OSError as e:
            raise ValueError(
                f"{self.what} {self.path} cannot be written: its folder {self.path.parent}: "
                f"{e.strerror or e}"
            ) from None
        if not got:
            raise ValueError(
                f"{self.what} {self.path} is being written by another nbvkit run "
                f"({self.lock.holder()}): two runs cannot share a folder; wait for it or choose "
                "another folder"
            )

    def release(self) -> None:
        self.lock.release()
