"""Writing files in the output directory without ever following a link:
a file is created with O_NOFOLLOW (a symbolic link where the file or its
temporary goes makes the write fail instead of overwriting the link's
target), and replaced atomically (written aside, flushed to disk, renamed)."""
import os

FLAGS = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0)


def open_new(path, mode="w", newline=None):
    """Open ``path`` for writing, created or truncated; OSError (ELOOP) if it
    is a symbolic link."""
    fd = os.open(path, FLAGS, 0o644)
    return os.fdopen(fd, mode, newline=newline)


def open_append(path, newline=None):
    """Open an existing ``path`` to append; OSError if it is a symbolic link."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | getattr(os, "O_NOFOLLOW", 0))
    return os.fdopen(fd, "a", newline=newline)


def atomic_write_text(path, text):
    """Replace ``path`` by ``text``: written to ``path.tmp`` first, fsynced,
    then renamed over ``path`` (readers see the old file or the new one)."""
    tmp = path + ".tmp"
    try:
        with open_new(tmp) as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:                              # a full disk: no half-written .tmp left behind
            os.unlink(tmp)
        except OSError:
            pass
        raise
